// Sensor CSV readers (hal/sensor_csv.hpp): the real EuRoC files, and written files for the formats
// and the errors.

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "hal_test_util.hpp"
#include "hwr/hal/sensor_csv.hpp"

namespace hwr::hal {
namespace {

using testing::expect_one_line_error;
using testing::kEurocImu40sMav0;
using testing::kEurocStaticMav0;
using testing::scratch_dir;
using testing::write_text;

TEST(SensorCsv, GivenEurocV101Imu_WhenRead_ThenAll29120RowsWithExactEnds) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  auto imu = read_imu_csv(kEurocStaticMav0 + "/imu0/data.csv");
  ASSERT_TRUE(imu.ok()) << imu.status().to_string();
  ASSERT_EQ(imu->size(), 29120u);
  EXPECT_EQ(imu->front().t_ns, 1403715273262142976LL);
  EXPECT_EQ(imu->back().t_ns, 1403715418857143040LL);
  // First row: w = (-0.0020943951023931952, 0.017453292519943295, 0.07749261878854824),
  //            a = (9.0874956666666655, 0.13075533333333333, -3.6938381666666662)
  EXPECT_DOUBLE_EQ(imu->front().gyro_radps.x(), -0.0020943951023931952);
  EXPECT_DOUBLE_EQ(imu->front().gyro_radps.z(), 0.07749261878854824);
  EXPECT_DOUBLE_EQ(imu->front().accel_mps2.x(), 9.0874956666666655);
  EXPECT_DOUBLE_EQ(imu->front().accel_mps2.z(), -3.6938381666666662);
  // Stationary start: specific force magnitude is gravity to within a few percent.
  EXPECT_NEAR(imu->front().accel_mps2.norm(), 9.81, 0.3);
}

TEST(SensorCsv, GivenEurocV102Imu_WhenRead_ThenAll7999RowsWithExactEnds) {
  HWR_REQUIRE_DATASET(kEurocImu40sMav0);
  auto imu = read_imu_csv(kEurocImu40sMav0 + "/imu0/data.csv");
  ASSERT_TRUE(imu.ok()) << imu.status().to_string();
  ASSERT_EQ(imu->size(), 7999u);
  EXPECT_EQ(imu->front().t_ns, 1403715523912140000LL);
  EXPECT_EQ(imu->back().t_ns, 1403715563902140000LL);
  EXPECT_DOUBLE_EQ(imu->back().accel_mps2.x(), 10.9997924167);
}

TEST(SensorCsv, GivenEurocStateGroundTruth_WhenRead_ThenRowsAndFieldsMatchTheFile) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  auto gt = read_euroc_state_csv(kEurocStaticMav0 + "/state_groundtruth_estimate0/data.csv");
  ASSERT_TRUE(gt.ok()) << gt.status().to_string();
  ASSERT_EQ(gt->size(), 2895u);
  EXPECT_EQ(gt->front().t_ns, 1403715273262142976LL);
  EXPECT_EQ(gt->back().t_ns, 1403715417962142976LL);
  // 1403715273262142976,0.878895,2.1834,0.948427,0.069433,-0.824237,-0.106942,-0.551702,
  //   0.00157587,0.00179383,-0.00231615,-0.00224703,0.0215352,0.0770299,-0.0180115,0.0659796,0.0309774
  const EurocState& s = gt->front();
  EXPECT_DOUBLE_EQ(s.p_world_body.x(), 0.878895);
  EXPECT_DOUBLE_EQ(s.p_world_body.z(), 0.948427);
  const Eigen::Quaterniond q_file =
      Eigen::Quaterniond(0.069433, -0.824237, -0.106942, -0.551702).normalized();
  EXPECT_NEAR(s.q_world_body.angularDistance(q_file), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.v_world_body_mps.y(), 0.00179383);
  EXPECT_DOUBLE_EQ(s.gyro_bias_radps.z(), 0.0770299);
  EXPECT_DOUBLE_EQ(s.accel_bias_mps2.x(), -0.0180115);
  EXPECT_TRUE(s.T_world_body().translation().isApprox(s.p_world_body));

  HWR_REQUIRE_DATASET(kEurocImu40sMav0);
  auto gt2 = read_euroc_state_csv(kEurocImu40sMav0 + "/gt0/data.csv");
  ASSERT_TRUE(gt2.ok()) << gt2.status().to_string();
  ASSERT_EQ(gt2->size(), 3340u);
  EXPECT_EQ(gt2->front().t_ns, 1403715524922140000LL);
  EXPECT_EQ(gt2->back().t_ns, 1403715608397140000LL);
}

TEST(SensorCsv, GivenMagAndGnssLogs_WhenRead_ThenFieldsAndNoFixRowsAreKept) {
  const auto dir = scratch_dir("mag_gnss");
  write_text(dir / "mag.csv",
             "#timestamp [ns],m_x [uT],m_y [uT],m_z [uT]\n"
             "1000,20.5,-3.25,-40\n"
             "2000, 21 , -3.5e0 ,-41.0\n");
  auto mag = read_mag_csv((dir / "mag.csv").string());
  ASSERT_TRUE(mag.ok()) << mag.status().to_string();
  ASSERT_EQ(mag->size(), 2u);
  EXPECT_EQ((*mag)[1].t_ns, 2000);
  EXPECT_EQ((*mag)[1].field_uT, Eigen::Vector3d(21, -3.5, -41));

  write_text(dir / "gnss.csv",
             "#timestamp [ns],lat [deg],lon [deg],height [m],h_acc [m],v_acc [m],fix_type,num_sv\n"
             "1000000000,nan,nan,nan,nan,nan,0,0\n"
             "2000000000,47.3769,8.5417,408.25,1.5,2.5,3,12\n");
  auto gnss = read_gnss_csv((dir / "gnss.csv").string());
  ASSERT_TRUE(gnss.ok()) << gnss.status().to_string();
  ASSERT_EQ(gnss->size(), 2u);
  EXPECT_EQ((*gnss)[0].fix_type, 0);
  EXPECT_TRUE(std::isnan((*gnss)[0].lat_deg));
  EXPECT_FALSE((*gnss)[0].has_3d_fix());
  EXPECT_TRUE((*gnss)[1].has_3d_fix());
  EXPECT_EQ((*gnss)[1].num_sv, 12);
  EXPECT_DOUBLE_EQ((*gnss)[1].lat_deg, 47.3769);
  EXPECT_DOUBLE_EQ((*gnss)[1].height_m, 408.25);
  EXPECT_DOUBLE_EQ((*gnss)[1].v_acc_m, 2.5);
}

TEST(SensorCsv, GivenAnEmptyLogWithOnlyAHeader_WhenRead_ThenNoSamplesAndNoError) {
  const auto dir = scratch_dir("empty");
  write_text(dir / "imu.csv", "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n");
  auto imu = read_imu_csv((dir / "imu.csv").string());
  ASSERT_TRUE(imu.ok()) << imu.status().to_string();
  EXPECT_TRUE(imu->empty());
}

struct BadCsv {
  const char* name;
  const char* text;
  const char* message;  // after "<path>:"
};

TEST(SensorCsv, GivenMalformedImuRows_WhenRead_ThenOneLineErrorNamesFileLineAndProblem) {
  const char* header = "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n1,0,0,0,0,0,9.8\n";
  const BadCsv cases[] = {
      {"short", "2,0,0,0,0,9.8\n",
       ":3: expected 7 comma-separated fields (timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z), got 6"},
      {"long", "2,0,0,0,0,0,9.8,1\n", ":3: expected 7 comma-separated fields"},
      {"text", "2,0,zero,0,0,0,9.8\n", ":3: field 3: not a finite number: 'zero'"},
      {"empty_field", "2,0,,0,0,0,9.8\n", ":3: field 3: not a finite number: ''"},
      {"nan", "2,0,0,nan,0,0,9.8\n", ":3: field 4: not a finite number: 'nan'"},
      {"float_stamp", "2.5,0,0,0,0,0,9.8\n", ":3: field 1 (timestamp [ns]): not an integer: '2.5'"},
      {"same_stamp", "1,0,0,0,0,0,9.8\n", ":3: timestamps must increase (1 after 1 on line 2)"},
      {"backwards", "0,0,0,0,0,0,9.8\n", ":3: timestamps must increase"},
      {"trailing_junk", "2,0,0,0,0,0,9.8x\n", ":3: field 7: not a finite number: '9.8x'"},
  };
  const auto dir = scratch_dir("bad_imu");
  for (const BadCsv& c : cases) {
    const std::string path = (dir / (std::string(c.name) + ".csv")).string();
    write_text(path, std::string(header) + c.text);
    auto imu = read_imu_csv(path);
    ASSERT_FALSE(imu.ok()) << c.name;
    EXPECT_EQ(imu.status().code(), core::ErrorCode::kParseError) << c.name;
    expect_one_line_error(imu.status(), path + c.message);
  }
}

TEST(SensorCsv, GivenMalformedMagGnssAndStateRows_WhenRead_ThenErrorsNameFileAndLine) {
  const auto dir = scratch_dir("bad_other");
  write_text(dir / "mag.csv", "#h\n1,2,3\n");
  expect_one_line_error(read_mag_csv((dir / "mag.csv").string()).status(),
                        (dir / "mag.csv").string() + ":2: expected 4 comma-separated fields");

  write_text(dir / "gnss_nan.csv", "#h\n1,nan,8.5,400,1,1,3,9\n");
  expect_one_line_error(read_gnss_csv((dir / "gnss_nan.csv").string()).status(),
                        ":2: field 2: not a finite number: 'nan' (only fix_type 0 rows may hold nan)");
  write_text(dir / "gnss_fix.csv", "#h\n1,47,8.5,400,1,1,7,9\n");
  expect_one_line_error(read_gnss_csv((dir / "gnss_fix.csv").string()).status(),
                        ":2: field 7 (fix_type): expected an integer 0..5, got '7'");
  write_text(dir / "gnss_sv.csv", "#h\n1,47,8.5,400,1,1,3,300\n");
  expect_one_line_error(read_gnss_csv((dir / "gnss_sv.csv").string()).status(), "field 8 (num_sv)");
  write_text(dir / "gnss_lat.csv", "#h\n1,147,8.5,400,1,1,3,9\n");
  expect_one_line_error(read_gnss_csv((dir / "gnss_lat.csv").string()).status(),
                        ":2: latitude/longitude out of range");

  write_text(dir / "state.csv", "#h\n1,0,0,0,2,0,0,0,0,0,0,0,0,0,0,0,0\n");
  expect_one_line_error(read_euroc_state_csv((dir / "state.csv").string()).status(),
                        ":2: quaternion (fields 5-8) has norm 2.000000, expected 1");
  write_text(dir / "state_short.csv", "#h\n1,0,0,0,1,0,0,0\n");
  expect_one_line_error(read_euroc_state_csv((dir / "state_short.csv").string()).status(),
                        ":2: expected 17 comma-separated fields");
}

TEST(SensorCsv, GivenAMissingFileOrAFolder_WhenRead_ThenErrorNamesThePath) {
  auto missing = read_imu_csv("/nonexistent/hwr/imu.csv");
  EXPECT_EQ(missing.status().code(), core::ErrorCode::kNotFound);
  expect_one_line_error(missing.status(), "/nonexistent/hwr/imu.csv: file not found");
  const auto dir = scratch_dir("folder");
  auto folder = read_imu_csv(dir.string());
  expect_one_line_error(folder.status(), dir.string() + ": is a directory");
}

}  // namespace
}  // namespace hwr::hal

namespace hwr::hal {
namespace {

TEST(SensorCsv, GivenDoubleSignsInAField_WhenRead_ThenTheLineIsRejected) {
  const auto dir = testing::scratch_dir("double_sign");
  for (const char* bad : {"+-1.0", "++1.0", "+"}) {
    testing::write_text(dir / "imu.csv",
                        std::string("#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n1000,0,0,0,0,0,") + bad + "\n");
    auto imu = read_imu_csv((dir / "imu.csv").string());
    ASSERT_FALSE(imu.ok()) << bad;
    EXPECT_NE(imu.status().message().find("imu.csv:2"), std::string::npos) << imu.status().message();
  }
  testing::write_text(dir / "imu.csv", "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n1000,0,0,0,0,0,+9.81\n");
  auto ok = read_imu_csv((dir / "imu.csv").string());
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_DOUBLE_EQ(ok.value()[0].accel_mps2.z(), 9.81);
}

}  // namespace
}  // namespace hwr::hal
