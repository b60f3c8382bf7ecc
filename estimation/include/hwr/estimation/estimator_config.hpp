#pragma once
// PoseEstimatorConfig from YAML (hwr-robot --config FILE, section `estimation:`), strict like
// every config in the project: unknown keys and wrong types are errors naming file, line and key.
// config/estimation.yaml lists every key with its default and unit.

#include <string>

#include "hwr/core/config.hpp"
#include "hwr/core/status.hpp"
#include "hwr/estimation/pose_estimator.hpp"

namespace hwr::estimation {

// Reads the keys present in `map` over *config (absent keys keep their values).
void read_estimator_config(core::ConfigMap map, PoseEstimatorConfig* config);
// Loads FILE's `estimation:` mapping over the defaults.
core::Expected<PoseEstimatorConfig> load_estimator_config(const std::string& path);

}  // namespace hwr::estimation
