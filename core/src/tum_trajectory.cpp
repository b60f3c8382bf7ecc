#include "hwr/core/tum_trajectory.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <sstream>

#include "hwr/core/file_io.hpp"
#include "hwr/core/timestamp_text.hpp"

namespace hwr::core {

Expected<std::vector<StampedPose>> parse_tum_trajectory(const std::string& text,
                                                        const std::string& source_name) {
  std::vector<StampedPose> out;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = source_name + ":" + std::to_string(line_no) + ": ";

    std::istringstream fields(line.substr(first));
    std::string tok[9];
    int n = 0;
    while (n < 9 && (fields >> tok[n])) ++n;
    if (n != 8) {
      return ParseError(where + "expected 8 numbers 'timestamp tx ty tz qx qy qz qw', got " +
                        std::to_string(n) + (n == 9 ? " or more" : ""));
    }
    StampedPose p;
    if (!parse_timestamp_s(tok[0], &p.t_ns)) return ParseError(where + "bad timestamp '" + tok[0] + "'");
    double v[7];
    for (int k = 0; k < 7; ++k) {
      char* end = nullptr;
      v[k] = std::strtod(tok[k + 1].c_str(), &end);
      if (end == tok[k + 1].c_str() || *end != '\0' || !std::isfinite(v[k])) {
        return ParseError(where + "field " + std::to_string(k + 2) + ": not a finite number: '" + tok[k + 1] +
                          "'");
      }
    }
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // file order qx qy qz qw
    const double norm = q.norm();
    if (std::fabs(norm - 1.0) > 1e-2) {
      return ParseError(where + "quaternion norm " + std::to_string(norm) + " is not 1");
    }
    q.normalize();
    if (!out.empty() && p.t_ns <= out.back().t_ns) {
      return ParseError(where + "timestamps must increase (" + tok[0] + " after " +
                        format_timestamp_s(out.back().t_ns, 9) + ")");
    }
    p.T_world_body.linear() = q.toRotationMatrix();
    p.T_world_body.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    out.push_back(p);
  }
  return out;
}

Expected<std::vector<StampedPose>> read_tum_trajectory(const std::string& path) {
  std::string text;
  HWR_RETURN_IF_ERROR(read_file(path, &text));
  return parse_tum_trajectory(text, path);
}

Status write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses,
                            const std::string& header_comment) {
  std::string text;
  text.reserve(96 * poses.size() + 128);
  if (!header_comment.empty()) text += "# " + header_comment + "\n";
  text += "# timestamp tx ty tz qx qy qz qw\n";
  char buf[256];
  for (const StampedPose& p : poses) {
    const Eigen::Quaterniond q(p.T_world_body.linear());
    const Eigen::Vector3d t = p.T_world_body.translation();
    std::snprintf(buf, sizeof(buf), " %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", t.x(), t.y(), t.z(), q.x(),
                  q.y(), q.z(), q.w());
    text += format_timestamp_s(p.t_ns, 9);
    text += buf;
  }
  return write_file_atomic(path, text);
}

}  // namespace hwr::core
