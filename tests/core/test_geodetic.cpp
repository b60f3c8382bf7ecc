// WGS-84 conversions against published pairs and against their own inverses.

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Dense>

#include "hwr/core/geodetic.hpp"

namespace hwr::core {
namespace {

TEST(Geodetic, GivenEquatorPrimeMeridianWhenToEcefThenSemiMajorAxisOnX) {
  const Eigen::Vector3d p = geodetic_to_ecef({0.0, 0.0, 0.0});
  EXPECT_NEAR(p.x(), 6378137.0, 1e-9);
  EXPECT_NEAR(p.y(), 0.0, 1e-9);
  EXPECT_NEAR(p.z(), 0.0, 1e-9);
}

TEST(Geodetic, GivenNorthPoleWhenToEcefThenSemiMinorAxisOnZ) {
  const Eigen::Vector3d p = geodetic_to_ecef({90.0, 0.0, 0.0});
  EXPECT_NEAR(p.x(), 0.0, 1e-6);
  EXPECT_NEAR(p.z(), kWgs84SemiMinorM, 1e-6);
  const Geodetic back = ecef_to_geodetic(p);
  EXPECT_NEAR(back.lat_deg, 90.0, 1e-12);
  EXPECT_NEAR(back.height_m, 0.0, 1e-6);
}

// Published pairs: pymap3d's test suite (42 N, 82 W, 200 m) and qzsl6tool's llh2ecef example.
TEST(Geodetic, GivenPublishedPairsWhenConvertedThenMatchToOneMillimetre) {
  struct Pair {
    Geodetic g;
    Eigen::Vector3d ecef;
  };
  const Pair pairs[] = {
      {{42.0, -82.0, 200.0}, {660675.2518247, -4700948.68316, 4245737.66222}},
      {{34.4401061, 132.4147804, 233.362}, {-3551876.829, 3887786.860, 3586946.387}},
  };
  for (const Pair& pr : pairs) {
    const Eigen::Vector3d p = geodetic_to_ecef(pr.g);
    // The second pair is printed to 1e-7 deg (~1 cm) and 1 mm: compare at its precision.
    EXPECT_LT((p - pr.ecef).norm(), 0.02);
    const Geodetic back = ecef_to_geodetic(pr.ecef);
    EXPECT_NEAR(back.lat_deg, pr.g.lat_deg, 1e-7);
    EXPECT_NEAR(back.lon_deg, pr.g.lon_deg, 1e-7);
    EXPECT_NEAR(back.height_m, pr.g.height_m, 2e-3);
  }
  // pymap3d's pair is exact to 1e-7 m: hold it to 1 mm.
  EXPECT_LT((geodetic_to_ecef(pairs[0].g) - pairs[0].ecef).norm(), 1e-3);
}

// MathWorks ecef2lla example: [4510731 4510731 0] -> (0, 45, 999.9564).
TEST(Geodetic, GivenMathworksExampleWhenToGeodeticThenHeightMatches) {
  const Geodetic g = ecef_to_geodetic({4510731.0, 4510731.0, 0.0});
  EXPECT_NEAR(g.lat_deg, 0.0, 1e-12);
  EXPECT_NEAR(g.lon_deg, 45.0, 1e-12);
  EXPECT_NEAR(g.height_m, 999.9564, 1e-4);
}

TEST(Geodetic, GivenManyPointsWhenRoundTripThroughEcefThenIdentity) {
  for (double lat = -89.5; lat <= 89.5; lat += 11.3) {
    for (double lon = -179.0; lon <= 179.0; lon += 37.7) {
      for (double h : {-100.0, 0.0, 450.0, 9000.0}) {
        const Geodetic back = ecef_to_geodetic(geodetic_to_ecef({lat, lon, h}));
        EXPECT_NEAR(back.lat_deg, lat, 1e-11);
        EXPECT_NEAR(back.lon_deg, lon, 1e-11);
        EXPECT_NEAR(back.height_m, h, 1e-6);
      }
    }
  }
}

TEST(Geodetic, GivenEnuFrameWhenAxesCheckedThenEastNorthUpAreOrthonormalAndUpIsNormal) {
  const Eigen::Matrix3d R = R_ecef_enu(47.3769, 8.5417);
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
  // Up is the direction in which height grows.
  const Geodetic o{47.3769, 8.5417, 408.0};
  const Eigen::Vector3d d = geodetic_to_ecef({o.lat_deg, o.lon_deg, o.height_m + 1.0}) - geodetic_to_ecef(o);
  EXPECT_LT((d - R.col(2)).norm(), 1e-8);
  // North is the direction in which latitude grows.
  const Eigen::Vector3d n = geodetic_to_enu({o.lat_deg + 1e-5, o.lon_deg, o.height_m}, o);
  EXPECT_GT(n.y(), 1.0);
  EXPECT_LT(std::abs(n.x()), 1e-6);
}

TEST(Geodetic, GivenLocalOffsetsWhenEnuRoundTripThenWithinMicrometre) {
  const Geodetic origin{47.3769, 8.5417, 408.0};
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(150.0, -80.0, 2.5), Eigen::Vector3d(-1234.5, 987.6, -30.0),
        Eigen::Vector3d(0.001, 0.002, 0.003)}) {
    const Eigen::Vector3d back = geodetic_to_enu(enu_to_geodetic(p, origin), origin);
    EXPECT_LT((back - p).norm(), 1e-6) << p.transpose();
  }
}

}  // namespace
}  // namespace hwr::core
