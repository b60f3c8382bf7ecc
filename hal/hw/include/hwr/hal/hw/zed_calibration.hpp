#pragma once
// The ZED 2i's factory calibration file, SN<serial>.conf (hardware.md "Calibration file"): an INI
// text with case-insensitive keys. Sections [LEFT_CAM_<R>] and [RIGHT_CAM_<R>] hold fx fy cx cy
// k1 k2 p1 p2 k3 in pixels of that resolution; [STEREO] holds Baseline (mm), TY_<R>, TZ_<R> (mm;
// files without the suffix, plain TY / TZ, are read too) and RX_<R>, CV_<R>, RZ_<R> (radians). <R> is
// 2K, FHD, HD or VGA by eye width 2208, 1920, 1280, 672.
//
// Frames. [Baseline, TY, TZ] is where the right camera sits in the left camera's frame (the ZED's
// right eye is +x, to the right, of the left eye: Baseline > 0). Rodrigues([RX, CV, RZ]) is the
// rotation zed-open-capture hands to cv::stereoRectify as R, which OpenCV defines as taking left
// camera coordinates into the right camera's (R_right_left); so hal::StereoRig's
// T_left_right = [R_right_leftᵀ | (Baseline, TY, TZ) / 1000]. The angles are ~1e-3 rad, so a
// convention mistake here would show as a sub-pixel row misalignment, not as wrong depth.

#include <cstdint>
#include <string>
#include <string_view>

#include "hwr/core/status.hpp"
#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {

// Errors: an eye width with no ZED mode, a missing section or key (named), a value that is not a
// number or not finite, non-positive focal lengths or baseline, and a file whose k1 and k2 are zero
// for both cameras (hardware.md: files written under a comma-decimal locale lose their distortion).
// source_name is used in messages (the file path).
core::Expected<hal::StereoRig> parse_zed_calibration(std::string_view text, int eye_width,
                                                     const std::string& source_name = "SN.conf");
core::Expected<hal::StereoRig> load_zed_calibration_file(const std::string& path, int eye_width);

// "SN<serial>.conf", the name Stereolabs serves a camera's calibration under.
std::string zed_calibration_file_name(uint32_t serial);

}  // namespace hwr::hal::hw
