#pragma once
// WGS-84 geodetic coordinates, Earth-centred Earth-fixed (ECEF) and local East-North-Up (ENU)
// frames. The simulator places its scene frame (x east, y north, z up) at a geodetic origin and
// turns antenna positions into GNSS fixes through these; the estimator goes back the same way.
// Reference: NIMA TR8350.2 (WGS-84 definition), eqs. (4-14) and (4-15) for geodetic -> ECEF.

#include <Eigen/Core>

namespace hwr::core {

// WGS-84 defining parameters (TR8350.2 table 3.1).
constexpr double kWgs84SemiMajorM = 6378137.0;
constexpr double kWgs84InverseFlattening = 298.257223563;
constexpr double kWgs84Flattening = 1.0 / kWgs84InverseFlattening;
constexpr double kWgs84EccentricitySq = kWgs84Flattening * (2.0 - kWgs84Flattening);
constexpr double kWgs84SemiMinorM = kWgs84SemiMajorM * (1.0 - kWgs84Flattening);

// Latitude and longitude in degrees, height above the ellipsoid in metres (what NAV-PVT's
// lat/lon/height report).
struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;
};

Eigen::Vector3d geodetic_to_ecef(const Geodetic& g);
// Fixed-point iteration on latitude (Bowring's form, converges by a factor e^2 ~ 0.0067 per step)
// with h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2(lat)), which stays well conditioned at
// the poles. Accurate to well below a micrometre for |h| < 1e5 m.
Geodetic ecef_to_geodetic(const Eigen::Vector3d& p_ecef_m);

// Rotation from ENU at (lat, lon) to ECEF: columns are east, north, up in ECEF.
Eigen::Matrix3d R_ecef_enu(double lat_deg, double lon_deg);

// Position relative to a local ENU frame whose origin is `origin` (on the ellipsoid normal).
Eigen::Vector3d geodetic_to_enu(const Geodetic& g, const Geodetic& origin);
Geodetic enu_to_geodetic(const Eigen::Vector3d& p_enu_m, const Geodetic& origin);

}  // namespace hwr::core
