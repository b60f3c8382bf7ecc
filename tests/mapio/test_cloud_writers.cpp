// PLY / PCD writers and readers (mapio/cloud_writers.hpp): exact headers as PLY 1.0 and PCD v0.7
// specify them, record bytes at the offsets the formats define, PCL's rgb packing, bit-exact round
// trips, atomic replacement, and corrupt files rejected before allocation. When PCL's command-line
// tools or Open3D are installed, an independent reader loads the files too.

#include <sys/wait.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "temp_dir.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/mapio/cloud_writers.hpp"

namespace {

namespace fs = std::filesystem;
using hwr::core::ErrorCode;
using hwr::mapio::CloudArrays;

struct TempDir : hwr::testing::TempDir {
  TempDir() : hwr::testing::TempDir("hwr_cloud_writers") {}
};

CloudArrays random_cloud(size_t n, bool normals, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-50.0f, 50.0f), unit(-1.0f, 1.0f);
  CloudArrays c;
  c.xyz.resize(3 * n);
  c.rgb.resize(3 * n);
  for (auto& v : c.xyz) v = pos(rng);
  for (auto& v : c.rgb) v = static_cast<uint8_t>(rng());
  if (normals) {
    c.has_normals = true;
    c.normals.resize(3 * n);
    for (auto& v : c.normals) v = unit(rng);
  }
  if (n > 0) {  // values whose bits must survive: extremes, a denormal, negative zero
    c.xyz[0] = -0.0f;
    c.xyz[1] = std::numeric_limits<float>::denorm_min();
    c.xyz[2] = std::numeric_limits<float>::max();
    c.rgb[0] = 0, c.rgb[1] = 255, c.rgb[2] = 128;
  }
  return c;
}

std::string read_bytes(const std::string& path) {
  std::string s;
  EXPECT_TRUE(hwr::core::read_file(path, &s).ok()) << path;
  return s;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

void expect_equal_clouds(const CloudArrays& want, const CloudArrays& got) {
  ASSERT_EQ(got.size(), want.size());
  EXPECT_EQ(got.has_normals, want.has_normals);
  EXPECT_TRUE(same_bits(got.xyz, want.xyz));
  EXPECT_EQ(got.rgb, want.rgb);
  EXPECT_TRUE(same_bits(got.normals, want.normals));
}

// A non-null normals pointer declares the normal fields, also for 0 points (where data() may be null).
const float* normals_ptr(const CloudArrays& c) {
  static const float kNoValues[3] = {};
  if (!c.has_normals) return nullptr;
  return c.normals.empty() ? kNoValues : c.normals.data();
}

// --- round trips -------------------------------------------------------------------------------------

struct RoundTripCase {
  size_t n;
  bool normals;
};

class CloudRoundTrip : public ::testing::TestWithParam<RoundTripCase> {};

TEST_P(CloudRoundTrip, GivenACloudWhenWrittenAndReadBackThenEveryValueIsBitIdentical) {
  const RoundTripCase p = GetParam();
  TempDir tmp;
  const CloudArrays cloud = random_cloud(p.n, p.normals, static_cast<uint32_t>(p.n * 2 + p.normals));
  const size_t ply_stride = p.normals ? 27 : 15, pcd_stride = p.normals ? 28 : 16;

  ASSERT_TRUE(
      hwr::mapio::write_ply(tmp.file("c.ply"), cloud.xyz.data(), cloud.rgb.data(), normals_ptr(cloud), p.n)
          .ok());
  CloudArrays ply;
  const auto st_ply = hwr::mapio::read_ply(tmp.file("c.ply"), &ply);
  ASSERT_TRUE(st_ply.ok()) << st_ply.to_string();
  expect_equal_clouds(cloud, ply);
  const std::string ply_bytes = read_bytes(tmp.file("c.ply"));
  EXPECT_EQ(ply_bytes.size(), ply_bytes.find("end_header\n") + 11 + p.n * ply_stride);

  ASSERT_TRUE(
      hwr::mapio::write_pcd(tmp.file("c.pcd"), cloud.xyz.data(), cloud.rgb.data(), normals_ptr(cloud), p.n)
          .ok());
  CloudArrays pcd;
  const auto st_pcd = hwr::mapio::read_pcd(tmp.file("c.pcd"), &pcd);
  ASSERT_TRUE(st_pcd.ok()) << st_pcd.to_string();
  expect_equal_clouds(cloud, pcd);
  const std::string pcd_bytes = read_bytes(tmp.file("c.pcd"));
  EXPECT_EQ(pcd_bytes.size(), pcd_bytes.find("DATA binary\n") + 12 + p.n * pcd_stride);

  EXPECT_FALSE(fs::exists(tmp.file("c.ply.tmp")));
  EXPECT_FALSE(fs::exists(tmp.file("c.pcd.tmp")));
}

INSTANTIATE_TEST_SUITE_P(Sizes, CloudRoundTrip,
                         ::testing::Values(RoundTripCase{0, false}, RoundTripCase{0, true},
                                           RoundTripCase{1, false}, RoundTripCase{1, true},
                                           RoundTripCase{10000, false}, RoundTripCase{10000, true}),
                         [](const ::testing::TestParamInfo<RoundTripCase>& param_info) {
                           return "n" + std::to_string(param_info.param.n) +
                                  (param_info.param.normals ? "_normals" : "");
                         });

// --- exact bytes -------------------------------------------------------------------------------------

// Little-endian bytes of a float, as the files must hold them.
std::string le_bytes(float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, 4);
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((bits >> (8 * i)) & 0xff);
  return s;
}

TEST(CloudWriters, GivenPointsWithNormalsThenThePlyHeaderAndRecordsAreExactlyPly10) {
  TempDir tmp;
  const std::vector<float> xyz = {1.5f, -2.0f, 3.25f, 0.0f, 1e-3f, -7.0f};
  const std::vector<uint8_t> rgb = {10, 20, 30, 255, 0, 128};
  const std::vector<float> normals = {0.0f, 0.0f, 1.0f, 0.6f, 0.8f, 0.0f};
  ASSERT_TRUE(hwr::mapio::write_ply(tmp.file("n.ply"), xyz.data(), rgb.data(), normals.data(), 2).ok());
  const std::string header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "element vertex 2\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property float nx\n"
      "property float ny\n"
      "property float nz\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "end_header\n";
  const std::string bytes = read_bytes(tmp.file("n.ply"));
  ASSERT_EQ(bytes.size(), header.size() + 2 * 27);
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  const std::string rec1 = bytes.substr(header.size() + 27, 27);
  EXPECT_EQ(rec1.substr(0, 4), le_bytes(0.0f));
  EXPECT_EQ(rec1.substr(4, 4), le_bytes(1e-3f));
  EXPECT_EQ(rec1.substr(8, 4), le_bytes(-7.0f));
  EXPECT_EQ(rec1.substr(12, 4), le_bytes(0.6f));
  EXPECT_EQ(rec1.substr(20, 4), le_bytes(0.0f));
  EXPECT_EQ(rec1.substr(24, 3), std::string("\xff\x00\x80", 3));
}

TEST(CloudWriters, GivenPointsWithoutNormalsThenThePlyHeaderHasOnlyPositionAndColour) {
  TempDir tmp;
  const std::vector<float> xyz = {1.0f, 2.0f, 3.0f};
  const std::vector<uint8_t> rgb = {1, 2, 3};
  ASSERT_TRUE(hwr::mapio::write_ply(tmp.file("p.ply"), xyz.data(), rgb.data(), nullptr, 1).ok());
  const std::string expected =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n" +
      le_bytes(1.0f) + le_bytes(2.0f) + le_bytes(3.0f) + std::string("\x01\x02\x03", 3);
  EXPECT_EQ(read_bytes(tmp.file("p.ply")), expected);
}

TEST(CloudWriters, GivenAColourThenPcdStoresItAsPclsPackedRgbFloat) {
  TempDir tmp;
  const std::vector<float> xyz = {0.5f, 0.25f, -1.0f, 4.0f, 5.0f, 6.0f};
  const std::vector<uint8_t> rgb = {0x12, 0x34, 0x56, 0xff, 0xff, 0xff};
  const std::vector<float> normals = {1.0f, 0.0f, 0.0f, 0.0f, -1.0f, 0.0f};
  ASSERT_TRUE(hwr::mapio::write_pcd(tmp.file("c.pcd"), xyz.data(), rgb.data(), normals.data(), 2).ok());
  const std::string header =
      "# .PCD v0.7 - Point Cloud Data file format\n"
      "VERSION 0.7\n"
      "FIELDS x y z rgb normal_x normal_y normal_z\n"
      "SIZE 4 4 4 4 4 4 4\n"
      "TYPE F F F F F F F\n"
      "COUNT 1 1 1 1 1 1 1\n"
      "WIDTH 2\n"
      "HEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\n"
      "POINTS 2\n"
      "DATA binary\n";
  const std::string bytes = read_bytes(tmp.file("c.pcd"));
  ASSERT_EQ(bytes.size(), header.size() + 2 * 28);
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  // PCL: uint32 (r << 16) | (g << 8) | b, stored little-endian in the 4 bytes of the float field.
  EXPECT_EQ(bytes.substr(header.size() + 12, 4), std::string("\x56\x34\x12\x00", 4));
  EXPECT_EQ(bytes.substr(header.size() + 28 + 12, 4), std::string("\xff\xff\xff\x00", 4));
  EXPECT_EQ(bytes.substr(header.size() + 28 + 16, 12), le_bytes(0.0f) + le_bytes(-1.0f) + le_bytes(0.0f));

  const float packed = hwr::mapio::pack_pcl_rgb(0x12, 0x34, 0x56);
  uint32_t bits;
  std::memcpy(&bits, &packed, 4);
  EXPECT_EQ(bits, 0x00123456u);
  uint8_t r = 0, g = 0, b = 0;
  hwr::mapio::unpack_pcl_rgb(packed, &r, &g, &b);
  EXPECT_EQ((std::vector<int>{r, g, b}), (std::vector<int>{0x12, 0x34, 0x56}));
}

TEST(CloudWriters, GivenNoNormalsThenThePcdHeaderHasFourFields) {
  TempDir tmp;
  ASSERT_TRUE(hwr::mapio::write_pcd(tmp.file("e.pcd"), nullptr, nullptr, nullptr, 0).ok());
  EXPECT_EQ(
      read_bytes(tmp.file("e.pcd")),
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\n"
      "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\nDATA binary\n");
}

// --- errors --------------------------------------------------------------------------------------------

TEST(CloudWriters, GivenCorruptOrForeignFilesThenTheReadersRejectThemWithoutAllocating) {
  TempDir tmp;
  CloudArrays out;
  EXPECT_EQ(hwr::mapio::read_ply(tmp.file("absent.ply"), &out).code(), ErrorCode::kNotFound);

  const std::string ply_header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("huge.ply"), ply_header + std::string(15, 'x')).ok());
  const auto huge = hwr::mapio::read_ply(tmp.file("huge.ply"), &out);
  EXPECT_EQ(huge.code(), ErrorCode::kCorruptData) << huge.to_string();
  EXPECT_NE(huge.message().find("1000000000 points"), std::string::npos) << huge.message();
  EXPECT_EQ(out.xyz.capacity(), 0u) << "nothing allocated for the claimed points";

  const std::vector<float> xyz = {1, 2, 3, 4, 5, 6};
  const std::vector<uint8_t> rgb = {1, 2, 3, 4, 5, 6};
  ASSERT_TRUE(hwr::mapio::write_ply(tmp.file("t.ply"), xyz.data(), rgb.data(), nullptr, 2).ok());
  fs::resize_file(tmp.file("t.ply"), fs::file_size(tmp.file("t.ply")) - 1);
  EXPECT_EQ(hwr::mapio::read_ply(tmp.file("t.ply"), &out).code(), ErrorCode::kCorruptData);

  ASSERT_TRUE(
      hwr::core::write_file_atomic(tmp.file("a.ply"), std::string("ply\nformat ascii 1.0\nelement vertex 0\n"
                                                                  "property float x\nend_header\n"))
          .ok());
  EXPECT_EQ(hwr::mapio::read_ply(tmp.file("a.ply"), &out).code(), ErrorCode::kParseError);
  ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("garbage.ply"), std::string(100000, 'g')).ok());
  EXPECT_EQ(hwr::mapio::read_ply(tmp.file("garbage.ply"), &out).code(), ErrorCode::kParseError);

  ASSERT_TRUE(hwr::mapio::write_pcd(tmp.file("t.pcd"), xyz.data(), rgb.data(), nullptr, 2).ok());
  std::string pcd = read_bytes(tmp.file("t.pcd"));
  std::string ascii = pcd;
  ascii.replace(ascii.find("DATA binary"), 11, "DATA ascii");
  ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("a.pcd"), ascii).ok());
  EXPECT_EQ(hwr::mapio::read_pcd(tmp.file("a.pcd"), &out).code(), ErrorCode::kParseError);
  std::string lying = pcd;
  lying.replace(lying.find("POINTS 2"), 8, "POINTS 3");
  ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("l.pcd"), lying).ok());
  EXPECT_EQ(hwr::mapio::read_pcd(tmp.file("l.pcd"), &out).code(), ErrorCode::kParseError)
      << "WIDTH != POINTS";
  lying.replace(lying.find("WIDTH 2"), 7, "WIDTH 3");
  ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("l.pcd"), lying).ok());
  EXPECT_EQ(hwr::mapio::read_pcd(tmp.file("l.pcd"), &out).code(), ErrorCode::kCorruptData);
}

TEST(CloudWriters, GivenAnExistingFileThenItIsReplacedWholeAndAMissingFolderIsAnIoError) {
  TempDir tmp;
  const CloudArrays big = random_cloud(5000, true, 1), small = random_cloud(3, false, 2);
  const std::string path = tmp.file("map.ply");
  ASSERT_TRUE(hwr::mapio::write_ply(path, big.xyz.data(), big.rgb.data(), big.normals.data(), 5000).ok());
  ASSERT_TRUE(hwr::mapio::write_ply(path, small.xyz.data(), small.rgb.data(), nullptr, 3).ok());
  CloudArrays got;
  ASSERT_TRUE(hwr::mapio::read_ply(path, &got).ok());
  expect_equal_clouds(small, got);
  EXPECT_FALSE(fs::exists(path + ".tmp"));

  const auto st =
      hwr::mapio::write_pcd(tmp.file("no/such/dir/map.pcd"), small.xyz.data(), small.rgb.data(), nullptr, 3);
  EXPECT_EQ(st.code(), ErrorCode::kIoError);
  EXPECT_NE(st.message().find("no/such/dir/map.pcd"), std::string::npos) << st.message();
  EXPECT_EQ(hwr::mapio::write_ply(path, nullptr, small.rgb.data(), nullptr, 3).code(),
            ErrorCode::kInvalidArgument);
}

// --- an independent reader, when one is installed ----------------------------------------------------

bool have_command(const std::string& check) { return std::system((check + " >/dev/null 2>&1").c_str()) == 0; }

TEST(CloudWriters, GivenOpen3dOrPclToolsThenTheyLoadOurFilesWithTheSameValues) {
  const bool open3d = have_command("python3 -c 'import open3d'");
  const bool pcl = have_command("command -v pcl_pcd2ply");
  if (!open3d && !pcl) GTEST_SKIP() << "neither python3 open3d nor PCL's pcl_pcd2ply is installed";
  TempDir tmp;
  const CloudArrays cloud = random_cloud(1000, true, 9);
  ASSERT_TRUE(
      hwr::mapio::write_ply(tmp.file("m.ply"), cloud.xyz.data(), cloud.rgb.data(), cloud.normals.data(), 1000)
          .ok());
  ASSERT_TRUE(
      hwr::mapio::write_pcd(tmp.file("m.pcd"), cloud.xyz.data(), cloud.rgb.data(), cloud.normals.data(), 1000)
          .ok());
  if (open3d) {
    // Open3D reports colours in [0, 1]; compare point 5's position and colour and the counts.
    const std::string script =
        "import open3d as o3d, sys\n"
        "for f in sys.argv[1:]:\n"
        "    c = o3d.io.read_point_cloud(f)\n"
        "    p = c.points[5]; k = c.colors[5]\n"
        "    print(len(c.points), c.has_normals(), '%.6g %.6g %.6g' % tuple(p), ' '.join(str(round(v * 255)) "
        "for v "
        "in k))\n";
    ASSERT_TRUE(hwr::core::write_file_atomic(tmp.file("check.py"), script).ok());
    const std::string cmd = "python3 " + tmp.file("check.py") + " " + tmp.file("m.ply") + " " +
                            tmp.file("m.pcd") + " > " + tmp.file("o");
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    char expect_line[200];
    std::snprintf(expect_line, sizeof(expect_line), "1000 True %.6g %.6g %.6g %d %d %d\n", cloud.xyz[15],
                  cloud.xyz[16], cloud.xyz[17], cloud.rgb[15], cloud.rgb[16], cloud.rgb[17]);
    EXPECT_EQ(read_bytes(tmp.file("o")), std::string(expect_line) + expect_line);
  }
  if (pcl) {
    const std::string cmd =
        "pcl_pcd2ply -format 1 " + tmp.file("m.pcd") + " " + tmp.file("pcl.ply") + " >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    const std::string bytes = read_bytes(tmp.file("pcl.ply"));
    EXPECT_NE(bytes.find("element vertex 1000\n"), std::string::npos) << "PCL read another point count";
  }
}

}  // namespace
