#pragma once
// LocalMapperConfig from YAML (hwr-robot --config FILE, section `map:`), strict like every config
// in the project. config/map.yaml lists every key with its default and unit.

#include "hwr/core/config.hpp"
#include "hwr/recon/local_mapper.hpp"

namespace hwr::recon {

// Reads the keys present in `map` over *config (absent keys keep their values).
void read_local_mapper_config(core::ConfigMap map, LocalMapperConfig* config);

}  // namespace hwr::recon
