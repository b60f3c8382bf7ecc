#pragma once
// Private to hal: decoding one image file into a caller-owned cv::Mat, with errors as Status.
// Truncated or corrupt files never crash: libpng's failures come back as an empty decode (OpenCV
// may still print its own diagnostic on stderr) and exceptions from OpenCV are caught here.

#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"

namespace hwr::hal {

// Reads `path` into *scratch (reused between calls) and decodes it with cv::imdecode `flags`
// into *out (reallocated only when size or type change). Missing file: NotFound; undecodable:
// CorruptData "<path>: cannot decode image (truncated or corrupt file, N bytes)".
core::Status decode_image_file(const std::string& path, int flags, std::vector<unsigned char>* scratch,
                               cv::Mat* out);

// "640x480 8UC3" for messages.
std::string describe_mat(const cv::Mat& m);

}  // namespace hwr::hal
