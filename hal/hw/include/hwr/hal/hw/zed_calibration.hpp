#pragma once
// The ZED 2i's factory calibration file, SN<serial>.conf (hardware.md "Calibration file"): INI text,
// section and key names case-insensitive, ';' or '#' comment lines, blank lines, CRLF or LF, spaces
// around '=', an optional UTF-8 byte-order mark. Sections [LEFT_CAM_<R>] and [RIGHT_CAM_<R>] hold
// fx fy cx cy (pixels at that resolution) and k1 k2 p1 p2 k3 (OpenCV's radial-tangential model);
// [STEREO] holds Baseline (mm), TY_<R>, TZ_<R> (mm; plain TY / TZ are read when the suffixed keys
// are absent) and RX_<R>, CV_<R>, RZ_<R> (radians). <R> is 2K, FHD, HD or VGA by eye width 2208,
// 1920, 1280, 672 (eye heights 1242, 1080, 720, 376).
//
// Frames and signs. hal::StereoRig wants T_left_right with p_left = T_left_right · p_right.
// stereolabs/zed-open-capture (examples/include/calibration.hpp, initCalibration) turns the file
// into cv::stereoRectify(K_l, D_l, K_r, D_r, size, R, T) with R = Rodrigues([RX, CV, RZ]) and
// T = [Baseline, TY, TZ]. OpenCV defines that pair as the motion from the first (left) camera to the
// second: p_right = R · p_left + T. So the file's rotation is R_right_left. Its translation, though,
// has the sign flipped with respect to OpenCV's: the right eye of a ZED sits at +x of the left eye
// (to the right as seen by the camera), which in OpenCV's convention is T = −R · c_right with
// c_right = (+B, ~0, ~0), i.e. T.x ≈ −B; the file writes Baseline > 0. stereoRectify's rectifying
// rotations do not depend on the sign of T (it aligns the new x axis with ±T), which is why
// zed-open-capture rectifies correctly with +B. We read the file as OpenCV's pair with that sign
// restored, T_right_left = [R | −t_file] with t_file = [Baseline, TY, TZ] / 1000 m, hence
//     T_left_right = T_right_left⁻¹ = [Rᵀ | Rᵀ · t_file],
// whose translation is the right camera's centre in the left frame: x ≈ +Baseline/1000 > 0. Fed to
// hal::StereoDepth (which inverts it back for cv::stereoRectify) the rig rectifies exactly as
// zed-open-capture's call does (tests/hal_hw/test_zed_calibration.cpp checks R1 against that call).
// The rotation's direction matters: CV_<R> (convergence, about y) of 3e-3 rad is ~1.6 px at HD; read
// transposed, rectification would be off by twice that in disparity.

#include <cstdint>
#include <string>
#include <string_view>

#include "hwr/core/status.hpp"
#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {

// text: the file's contents; eye_width: one eye's image width (half the side-by-side frame).
// Required: fx fy cx cy k1 k2 in both camera sections, Baseline, TY, TZ, RX, CV, RZ. p1 p2 k3 default
// to 0 when absent (files written by Stereolabs' own "ZED Calibration" tool have no p1/p2 and
// older factory files no k3: stereolabs/zed-sdk issue #182). Errors (each naming the file, the
// section and key, and the line where there is one): an eye width with no ZED mode
// (kInvalidArgument); a missing section or key, e.g. the resolution absent from the file (kNotFound);
// a malformed line or a value that is not a finite number, e.g. "532,41" (kParseError); non-positive
// focal lengths, a principal point outside the image, a baseline outside (0, 1000) mm, |TY| or |TZ|
// not below the baseline, a rotation |(RX, CV, RZ)| above 0.2 rad (kOutOfRange);
// k1 and k2 zero for both cameras (kCorruptData: hardware.md, zed-open-capture "Safety check A":
// a file saved under a comma-decimal locale loses its distortion). source_name is used in messages.
core::Expected<hal::StereoRig> parse_zed_calibration(std::string_view text, int eye_width,
                                                     const std::string& source_name = "SN.conf");
// Reads path and parses it (path in every message; a missing file says where to download it).
core::Expected<hal::StereoRig> load_zed_calibration_file(const std::string& path, int eye_width);

// "SN<serial>.conf", the name Stereolabs serves a camera's calibration under
// (https://calib.stereolabs.com/?SN=<serial>).
std::string zed_calibration_file_name(uint32_t serial);

}  // namespace hwr::hal::hw
