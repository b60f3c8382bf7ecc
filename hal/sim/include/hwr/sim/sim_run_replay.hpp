#pragma once
// A run written by hwr-sim (docs/simulator.md) as a replay log: the TUM-layout images through
// hal::TumDataset with the run's own intrinsics and depth scale, imu.csv, mag.csv and gnss.csv
// when present, and the camera-IMU extrinsic from calibration.yaml.

#include <string>

#include "hwr/core/status.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/sim/sim_calibration.hpp"

namespace hwr::sim {

struct SimRunLog {
  hal::ReplayLog log;
  SimCalibration calibration;
};

core::Expected<SimRunLog> open_sim_run_log(const std::string& dir);

}  // namespace hwr::sim
