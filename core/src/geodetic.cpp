#include "hwr/core/geodetic.hpp"

#include <cmath>

namespace hwr::core {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Prime-vertical radius of curvature N(lat) (TR8350.2 eq. 4-15).
double prime_vertical_radius(double sin_lat) {
  return kWgs84SemiMajorM / std::sqrt(1.0 - kWgs84EccentricitySq * sin_lat * sin_lat);
}

}  // namespace

Eigen::Vector3d geodetic_to_ecef(const Geodetic& g) {
  const double lat = g.lat_deg * kDegToRad;
  const double lon = g.lon_deg * kDegToRad;
  const double sl = std::sin(lat), cl = std::cos(lat);
  const double n = prime_vertical_radius(sl);
  // TR8350.2 eq. (4-14).
  return {(n + g.height_m) * cl * std::cos(lon), (n + g.height_m) * cl * std::sin(lon),
          (n * (1.0 - kWgs84EccentricitySq) + g.height_m) * sl};
}

Geodetic ecef_to_geodetic(const Eigen::Vector3d& p_ecef_m) {
  const double x = p_ecef_m.x(), y = p_ecef_m.y(), z = p_ecef_m.z();
  const double p = std::hypot(x, y);
  // Start from the geocentric-to-geodetic approximation for a point on the ellipsoid.
  double lat = std::atan2(z, p * (1.0 - kWgs84EccentricitySq));
  for (int i = 0; i < 8; ++i) {
    // tan(lat) = (z + e^2 N sin(lat)) / p: the ellipsoid normal through the point.
    const double sl = std::sin(lat);
    const double next = std::atan2(z + kWgs84EccentricitySq * prime_vertical_radius(sl) * sl, p);
    if (next == lat) break;
    lat = next;
  }
  const double sl = std::sin(lat), cl = std::cos(lat);
  Geodetic g;
  g.lat_deg = lat / kDegToRad;
  g.lon_deg = (p == 0.0) ? 0.0 : std::atan2(y, x) / kDegToRad;
  g.height_m = p * cl + z * sl - kWgs84SemiMajorM * std::sqrt(1.0 - kWgs84EccentricitySq * sl * sl);
  return g;
}

Eigen::Matrix3d R_ecef_enu(double lat_deg, double lon_deg) {
  const double lat = lat_deg * kDegToRad, lon = lon_deg * kDegToRad;
  const double sl = std::sin(lat), cl = std::cos(lat), so = std::sin(lon), co = std::cos(lon);
  Eigen::Matrix3d R;
  R.col(0) << -so, co, 0.0;            // east
  R.col(1) << -sl * co, -sl * so, cl;  // north
  R.col(2) << cl * co, cl * so, sl;    // up
  return R;
}

Eigen::Vector3d geodetic_to_enu(const Geodetic& g, const Geodetic& origin) {
  const Eigen::Vector3d d = geodetic_to_ecef(g) - geodetic_to_ecef(origin);
  return R_ecef_enu(origin.lat_deg, origin.lon_deg).transpose() * d;
}

Geodetic enu_to_geodetic(const Eigen::Vector3d& p_enu_m, const Geodetic& origin) {
  const Eigen::Vector3d p_ecef =
      geodetic_to_ecef(origin) + R_ecef_enu(origin.lat_deg, origin.lon_deg) * p_enu_m;
  return ecef_to_geodetic(p_ecef);
}

}  // namespace hwr::core
