#include "image_file.hpp"

#include <filesystem>
#include <fstream>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace hwr::hal {

core::Status decode_image_file(const std::string& path, int flags, std::vector<unsigned char>* scratch,
                               cv::Mat* out) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) {
    if (ec == std::errc::no_such_file_or_directory) return core::NotFound(path + ": image file not found");
    return core::IoError(path + ": cannot stat image file: " + ec.message());
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) return core::IoError(path + ": cannot open image file");
  scratch->resize(static_cast<size_t>(size));
  if (size > 0 && !f.read(reinterpret_cast<char*>(scratch->data()), static_cast<std::streamsize>(size))) {
    return core::IoError(path + ": read failed");
  }
  const std::string corrupt =
      path + ": cannot decode image (truncated or corrupt file, " + std::to_string(size) + " bytes)";
  if (size == 0) return core::CorruptData(corrupt);
  try {
    cv::imdecode(*scratch, flags, out);
  } catch (const cv::Exception& e) {
    return core::CorruptData(corrupt + ": " + e.err);
  }
  if (out->empty()) return core::CorruptData(corrupt);
  return core::Status::Ok();
}

std::string describe_mat(const cv::Mat& m) {
  return std::to_string(m.cols) + "x" + std::to_string(m.rows) + " " + cv::typeToString(m.type()).substr(3);
}

}  // namespace hwr::hal
