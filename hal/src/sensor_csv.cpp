#include "hwr/hal/sensor_csv.hpp"

#include <cmath>
#include <limits>
#include <string_view>

#include "text_table.hpp"

namespace hwr::hal {
namespace {

using core::Expected;
using core::ParseError;
using core::Status;

// Reads a CSV whose rows have exactly N fields, the first an integer t_ns strictly increasing.
// row(where, fields, t_ns) parses the rest of one row.
template <size_t N, class RowFn>
Status read_stamped_csv(const std::string& path, const char* columns, RowFn&& row) {
  std::string text;
  HWR_RETURN_IF_ERROR(text::read_file(path, &text));
  std::string_view f[N];
  int64_t last_t_ns = std::numeric_limits<int64_t>::min();
  int last_line = 0;
  return text::for_each_data_line(text, [&](int line_no, std::string_view line) -> Status {
    const std::string where = text::where(path, line_no);
    const size_t n = text::split_fields(line, ',', f, N);
    if (n != N) {
      return ParseError(where + "expected " + std::to_string(N) + " comma-separated fields (" + columns +
                        "), got " + std::to_string(n));
    }
    int64_t t_ns = 0;
    if (!text::parse_int64(f[0], &t_ns)) {
      return ParseError(where + "field 1 (timestamp [ns]): not an integer: " + text::quote(f[0]));
    }
    if (last_line != 0 && t_ns <= last_t_ns) {
      return ParseError(where + "timestamps must increase (" + std::to_string(t_ns) + " after " +
                        std::to_string(last_t_ns) + " on line " + std::to_string(last_line) + ")");
    }
    last_t_ns = t_ns;
    last_line = line_no;
    return row(where, f, t_ns);
  });
}

Status number(const std::string& where, const std::string_view* f, size_t k, double* out) {
  if (!text::parse_double(f[k], out)) {
    return ParseError(where + "field " + std::to_string(k + 1) +
                      ": not a finite number: " + text::quote(f[k]));
  }
  return Status::Ok();
}

Status vec3(const std::string& where, const std::string_view* f, size_t k, Eigen::Vector3d* out) {
  for (int i = 0; i < 3; ++i) HWR_RETURN_IF_ERROR(number(where, f, k + i, &(*out)[i]));
  return Status::Ok();
}

}  // namespace

Expected<std::vector<ImuSample>> read_imu_csv(const std::string& path) {
  std::vector<ImuSample> out;
  Status st = read_stamped_csv<7>(path, "timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z",
                                  [&](const std::string& where, const std::string_view* f, int64_t t_ns) {
                                    ImuSample s;
                                    s.t_ns = t_ns;
                                    HWR_RETURN_IF_ERROR(vec3(where, f, 1, &s.gyro_radps));
                                    HWR_RETURN_IF_ERROR(vec3(where, f, 4, &s.accel_mps2));
                                    out.push_back(s);
                                    return Status::Ok();
                                  });
  if (!st.ok()) return st;
  return out;
}

Expected<std::vector<MagSample>> read_mag_csv(const std::string& path) {
  std::vector<MagSample> out;
  Status st = read_stamped_csv<4>(path, "timestamp [ns],m_x [uT],m_y [uT],m_z [uT]",
                                  [&](const std::string& where, const std::string_view* f, int64_t t_ns) {
                                    MagSample s;
                                    s.t_ns = t_ns;
                                    HWR_RETURN_IF_ERROR(vec3(where, f, 1, &s.field_uT));
                                    out.push_back(s);
                                    return Status::Ok();
                                  });
  if (!st.ok()) return st;
  return out;
}

Expected<std::vector<GnssFix>> read_gnss_csv(const std::string& path) {
  std::vector<GnssFix> out;
  Status st = read_stamped_csv<8>(
      path, "timestamp [ns],lat [deg],lon [deg],height [m],h_acc [m],v_acc [m],fix_type,num_sv",
      [&](const std::string& where, const std::string_view* f, int64_t t_ns) {
        GnssFix g;
        g.t_ns = t_ns;
        int64_t fix_type = 0;
        int64_t num_sv = 0;
        if (!text::parse_int64(f[6], &fix_type) || fix_type < 0 || fix_type > 5) {
          return ParseError(where + "field 7 (fix_type): expected an integer 0..5, got " + text::quote(f[6]));
        }
        if (!text::parse_int64(f[7], &num_sv) || num_sv < 0 || num_sv > 255) {
          return ParseError(where + "field 8 (num_sv): expected an integer 0..255, got " + text::quote(f[7]));
        }
        g.fix_type = static_cast<uint8_t>(fix_type);
        g.num_sv = static_cast<uint8_t>(num_sv);
        double* reals[5] = {&g.lat_deg, &g.lon_deg, &g.height_m, &g.h_acc_m, &g.v_acc_m};
        for (size_t k = 0; k < 5; ++k) {
          const bool ok = fix_type == 0 ? text::parse_double_or_nan(f[k + 1], reals[k])
                                        : text::parse_double(f[k + 1], reals[k]);
          if (!ok) {
            return ParseError(where + "field " + std::to_string(k + 2) +
                              ": not a finite number: " + text::quote(f[k + 1]) +
                              (fix_type == 0 ? "" : " (only fix_type 0 rows may hold nan)"));
          }
        }
        if (fix_type != 0 && (std::fabs(g.lat_deg) > 90.0 || std::fabs(g.lon_deg) > 180.0)) {
          return ParseError(where + "latitude/longitude out of range");
        }
        out.push_back(g);
        return Status::Ok();
      });
  if (!st.ok()) return st;
  return out;
}

Expected<std::vector<EurocState>> read_euroc_state_csv(const std::string& path) {
  std::vector<EurocState> out;
  Status st = read_stamped_csv<17>(
      path, "timestamp [ns],p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x,v_y,v_z,bw_x,bw_y,bw_z,ba_x,ba_y,ba_z",
      [&](const std::string& where, const std::string_view* f, int64_t t_ns) {
        EurocState s;
        s.t_ns = t_ns;
        double q[4];
        HWR_RETURN_IF_ERROR(vec3(where, f, 1, &s.p_world_body));
        for (int i = 0; i < 4; ++i) HWR_RETURN_IF_ERROR(number(where, f, 4 + i, &q[i]));
        HWR_RETURN_IF_ERROR(vec3(where, f, 8, &s.v_world_body_mps));
        HWR_RETURN_IF_ERROR(vec3(where, f, 11, &s.gyro_bias_radps));
        HWR_RETURN_IF_ERROR(vec3(where, f, 14, &s.accel_bias_mps2));
        s.q_world_body = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);  // file order w x y z
        const double norm = s.q_world_body.norm();
        if (std::fabs(norm - 1.0) > 1e-2) {
          return ParseError(where + "quaternion (fields 5-8) has norm " + std::to_string(norm) +
                            ", expected 1");
        }
        s.q_world_body.normalize();
        out.push_back(s);
        return Status::Ok();
      });
  if (!st.ok()) return st;
  return out;
}

}  // namespace hwr::hal
