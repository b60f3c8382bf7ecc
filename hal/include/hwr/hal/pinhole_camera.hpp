#pragma once
// Pinhole intrinsics in OpenCV's convention (x right, y down, z forward; pixel centres at
// integer coordinates). Distortion in OpenCV order k1 k2 p1 p2 k3; all zero for rectified or
// already-undistorted images (TUM, rectified EuRoC, the simulator).

#include <array>

namespace hwr::hal {

struct PinholeIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3

  bool valid() const { return width > 0 && height > 0 && fx > 0 && fy > 0; }
};

}  // namespace hwr::hal
