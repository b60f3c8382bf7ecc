// Config reading is strict, and every error names file:line and the full dotted key (config.hpp).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "hwr/core/config.hpp"

namespace hwr::core {
namespace {

ConfigDocument parse_ok(const std::string& text) {
  auto doc = ConfigDocument::parse(text, "lab.yaml");
  EXPECT_TRUE(doc.ok()) << doc.status().to_string();
  return std::move(doc).value();
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

constexpr const char* kFullConfig = R"(seed: 42
name: weld_cell_a
scale: 0.5
enabled: yes
big: 12345678901
count: 7
camera:
  fx: 525.0
  fy: 525
  intrinsics:
    c: [319.5, 239.5]
  gravity: [0, 0, -9.81]
  q: [1, 0, 0, 0]
weights: [0.25, 0.5, 0.25]
plates:
  - name: left
    size: [1.0, 2.0, 0.01]
  - name: right
    size: [1.5, 2.0, 0.01]
)";

TEST(Config, GivenValidDocumentWhenEveryKeyIsReadThenValuesAreTypedAndFinishIsOk) {
  ConfigDocument doc = parse_ok(kFullConfig);
  ConfigMap root = doc.root();
  int64_t seed = 0;
  std::string name;
  float scale = 0;
  bool enabled = false;
  uint64_t big = 0;
  int count = 0;
  std::vector<double> weights;
  root.require("seed", &seed).get("name", &name).get("scale", &scale).get("enabled", &enabled);
  root.get("big", &big).get("count", &count).get("weights", &weights);
  ConfigMap cam = root.child("camera");
  EXPECT_EQ(cam.path(), "camera");
  EXPECT_EQ(cam.line(), 8);
  double fx = 0, fy = 0;
  Eigen::Vector3d g;
  Eigen::Vector4d q;
  Eigen::Vector2d c;
  cam.require("fx", &fx).require("fy", &fy).get("gravity", &g).get("q", &q);
  cam.child("intrinsics").require("c", &c);
  std::vector<std::string> plate_names;
  std::vector<Eigen::Vector3d> sizes;
  for (ConfigMap& p : root.list("plates")) {
    std::string n;
    Eigen::Vector3d s;
    p.require("name", &n).require("size", &s);
    plate_names.push_back(n);
    sizes.push_back(s);
  }
  EXPECT_TRUE(doc.finish().ok()) << doc.finish().to_string();
  EXPECT_TRUE(doc.all_errors().empty());

  EXPECT_EQ(seed, 42);
  EXPECT_EQ(name, "weld_cell_a");
  EXPECT_EQ(scale, 0.5f);
  EXPECT_TRUE(enabled);
  EXPECT_EQ(big, 12345678901u);
  EXPECT_EQ(count, 7);
  EXPECT_EQ(weights, (std::vector<double>{0.25, 0.5, 0.25}));
  EXPECT_EQ(fx, 525.0);
  EXPECT_EQ(fy, 525.0);
  EXPECT_EQ(g, Eigen::Vector3d(0, 0, -9.81));
  EXPECT_EQ(q, Eigen::Vector4d(1, 0, 0, 0));
  EXPECT_EQ(c, Eigen::Vector2d(319.5, 239.5));
  EXPECT_EQ(plate_names, (std::vector<std::string>{"left", "right"}));
  EXPECT_EQ(sizes[1], Eigen::Vector3d(1.5, 2.0, 0.01));
  EXPECT_EQ(root.keys().front(), "seed");
  EXPECT_EQ(root.keys().size(), 9u);
}

TEST(Config, GivenUnknownKeysWhenFinishedThenErrorNamesFileLineAndFullDottedKey) {
  ConfigDocument doc = parse_ok("seed: 1\nsped: 2\ncamera:\n  fx: 1\n  intrinsics:\n    fz: 3\n");
  ConfigMap root = doc.root();
  int seed = 0;
  double fx = 0;
  root.get("seed", &seed);
  ConfigMap cam = root.child("camera");
  cam.get("fx", &fx);
  cam.child("intrinsics");
  const Status st = doc.finish();
  EXPECT_EQ(st.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(st.message(), "lab.yaml:2: unknown key 'sped'");
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 2u);
  EXPECT_EQ(errs[1], "lab.yaml:6: unknown key 'camera.intrinsics.fz'");
}

TEST(Config, GivenUnreadSubtreeWhenFinishedThenOnlyItsRootKeyIsReported) {
  ConfigDocument doc = parse_ok("camera:\n  fx: 1\n  fy: 2\n");
  doc.root();
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 1u);
  EXPECT_EQ(errs[0], "lab.yaml:1: unknown key 'camera'");
}

TEST(Config, GivenUnknownKeyInListElementWhenFinishedThenPathHasTheIndex) {
  ConfigDocument doc = parse_ok("plates:\n  - name: a\n  - name: b\n    colour: red\n");
  for (ConfigMap& p : doc.root().list("plates")) {
    std::string n;
    p.get("name", &n);
  }
  EXPECT_EQ(doc.finish().message(), "lab.yaml:4: unknown key 'plates[1].colour'");
}

TEST(Config, GivenWrongTypesWhenReadThenErrorNamesKeyExpectationAndValueAndDefaultIsKept) {
  ConfigDocument doc = parse_ok("camera:\n  fx: fast\n  n: 2.5\n  on: maybe\n  name: [1, 2]\nrate: {a: 1}\n");
  ConfigMap cam = doc.root().child("camera");
  double fx = 1.0;
  int n = 3;
  bool on = false;
  std::string name = "keep";
  cam.get("fx", &fx).get("n", &n).get("on", &on).get("name", &name);
  double rate = 9;
  doc.root().get("rate", &rate);
  EXPECT_EQ(fx, 1.0);
  EXPECT_EQ(n, 3);
  EXPECT_FALSE(on);
  EXPECT_EQ(name, "keep");
  EXPECT_EQ(rate, 9);
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 5u);
  EXPECT_EQ(errs[0], "lab.yaml:2: key 'camera.fx': expected a number, got 'fast'");
  EXPECT_EQ(errs[1], "lab.yaml:3: key 'camera.n': expected an integer, got '2.5'");
  EXPECT_EQ(errs[2], "lab.yaml:4: key 'camera.on': expected true or false, got 'maybe'");
  EXPECT_EQ(errs[3], "lab.yaml:5: key 'camera.name': expected a text value, got a list");
  EXPECT_EQ(errs[4], "lab.yaml:6: key 'rate': expected a number, got a mapping");
  EXPECT_EQ(doc.finish().message(), errs[0]);
}

TEST(Config, GivenMissingRequiredKeysWhenFinishedThenErrorNamesTheFullKey) {
  ConfigDocument doc = parse_ok("seed: 1\ncamera:\n  fy: 2\n");
  ConfigMap root = doc.root();
  int seed = 0;
  double fx = 0, fy = 0, depth = 0;
  root.require("seed", &seed);
  ConfigMap cam = root.child("camera");
  cam.require("fx", &fx).require("fy", &fy);
  root.child("depth").require("scale", &depth);  // a whole absent section
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 2u);
  EXPECT_EQ(errs[0], "lab.yaml:3: key 'camera.fx': required but missing");
  // Reported against the nearest mapping that exists (the root starts on line 1).
  EXPECT_EQ(errs[1], "lab.yaml:1: key 'depth.scale': required but missing");
  EXPECT_EQ(fy, 2.0);
}

TEST(Config, GivenEmptyFileWhenReadThenEmptyMappingWithDefaultsAndRequiredKeysMissing) {
  ConfigDocument doc = parse_ok("");
  ConfigMap root = doc.root();
  EXPECT_TRUE(root.keys().empty());
  double x = 4.0;
  root.get("x", &x);
  EXPECT_EQ(x, 4.0);
  EXPECT_TRUE(root.child("camera").keys().empty());
  EXPECT_TRUE(root.list("plates").empty());
  EXPECT_TRUE(doc.finish().ok());
  root.require("seed", &x);
  EXPECT_TRUE(contains(doc.finish().message(), "key 'seed': required but missing"));

  // Comments only is empty too.
  EXPECT_TRUE(parse_ok("# nothing here\n").finish().ok());
}

TEST(Config, GivenYamlSyntaxErrorWhenParsedThenParseErrorWithTheLine) {
  auto doc = ConfigDocument::parse("a: 1\nb: 2\nc: [1, 2\nd: 4\n", "bad.yaml");
  ASSERT_FALSE(doc.ok());
  EXPECT_EQ(doc.status().code(), ErrorCode::kParseError);
  EXPECT_TRUE(contains(doc.status().message(), "bad.yaml:")) << doc.status().message();
  EXPECT_TRUE(contains(doc.status().message(), "YAML syntax error")) << doc.status().message();

  auto tab = ConfigDocument::parse("a: 1\nb:\n  c: 1\n d: 2\n", "indent.yaml");
  ASSERT_FALSE(tab.ok());
  EXPECT_TRUE(contains(tab.status().message(), "indent.yaml:4:")) << tab.status().message();
}

TEST(Config, GivenStructuralProblemsWhenParsedThenParseErrorNamesThem) {
  auto list = ConfigDocument::parse("- a\n- b\n", "list.yaml");
  ASSERT_FALSE(list.ok());
  EXPECT_TRUE(contains(list.status().message(), "list.yaml:1: the top level must be a mapping"));

  auto dup = ConfigDocument::parse("a: 1\nb: 2\na: 3\n", "dup.yaml");
  ASSERT_FALSE(dup.ok());
  EXPECT_EQ(dup.status().message(), "dup.yaml:3: duplicate key 'a'");
}

TEST(Config, GivenVectorsOfWrongLengthOrContentWhenReadThenErrorsNameTheKey) {
  ConfigDocument doc = parse_ok("g: [0, -9.81]\nh: [1, x, 3]\ni: 5\nj: [1, 2, 3, 4]\n");
  Eigen::Vector3d g(1, 2, 3), h(1, 2, 3), i(1, 2, 3), j(1, 2, 3);
  doc.root().get("g", &g).get("h", &h).get("i", &i).get("j", &j);
  EXPECT_EQ(g, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(h, Eigen::Vector3d(1, 2, 3));
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 4u);
  EXPECT_EQ(errs[0], "lab.yaml:1: key 'g': expected 3 numbers, got 2");
  EXPECT_EQ(errs[1], "lab.yaml:2: key 'h': element 1: expected a number, got 'x'");
  EXPECT_EQ(errs[2], "lab.yaml:3: key 'i': expected a list of numbers, got '5'");
  EXPECT_EQ(errs[3], "lab.yaml:4: key 'j': expected 3 numbers, got 4");
}

TEST(Config, GivenNumberSpellingsWhenReadThenYamlMeaningIsKept) {
  ConfigDocument doc = parse_ok(
      "dec: 010\nhex: 0x1F\noct: 0o17\nsci: 1e6\nneg: -42\nbig: 3000000000\nnegu: -1\n"
      "tiny: 1e-310\nnan: .nan\ninf: -.inf\nwhole: 30.0\n");
  ConfigMap r = doc.root();
  int dec = 0, hex = 0, oct = 0, sci = 0, neg = 0, big = 0, whole = 0;
  uint64_t negu = 5;
  double tiny = 1, nan = 0, inf = 0;
  r.get("dec", &dec).get("hex", &hex).get("oct", &oct).get("sci", &sci).get("neg", &neg).get("big", &big);
  r.get("negu", &negu).get("tiny", &tiny).get("nan", &nan).get("inf", &inf).get("whole", &whole);
  EXPECT_EQ(dec, 10);  // YAML 1.2: a leading zero is still decimal
  EXPECT_EQ(hex, 31);
  EXPECT_EQ(oct, 15);
  EXPECT_EQ(sci, 1000000);
  EXPECT_EQ(neg, -42);
  EXPECT_EQ(whole, 30);
  EXPECT_GT(tiny, 0.0);  // subnormal, not an error
  EXPECT_LT(tiny, 1e-300);
  EXPECT_TRUE(std::isnan(nan));
  EXPECT_TRUE(std::isinf(inf) && inf < 0);
  EXPECT_EQ(big, 0);
  EXPECT_EQ(negu, 5u);
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 2u);
  EXPECT_EQ(errs[0], "lab.yaml:6: key 'big': integer 3000000000 out of range");
  EXPECT_EQ(errs[1], "lab.yaml:7: key 'negu': expected a non-negative integer, got -1");
}

TEST(Config, GivenChildOrListOfWrongKindWhenReadThenErrorAndEmptyResult) {
  ConfigDocument doc = parse_ok("camera: 5\nplates: 3\nposes:\n  - 1\n  - {x: 2}\n");
  ConfigMap cam = doc.root().child("camera");
  EXPECT_TRUE(cam.keys().empty());
  EXPECT_TRUE(doc.root().list("plates").empty());
  std::vector<ConfigMap> poses = doc.root().list("poses");
  ASSERT_EQ(poses.size(), 1u);
  double x = 0;
  poses[0].get("x", &x);
  EXPECT_EQ(x, 2.0);
  const std::vector<std::string> errs = doc.all_errors();
  ASSERT_EQ(errs.size(), 3u);
  EXPECT_EQ(errs[0], "lab.yaml:1: key 'camera': expected a mapping of keys, got '5'");
  EXPECT_EQ(errs[1], "lab.yaml:2: key 'plates': expected a list, got '3'");
  EXPECT_EQ(errs[2], "lab.yaml:3: key 'poses': element 0: expected a mapping of keys, got '1'");
}

TEST(Config, GivenRangeCheckBeyondTypesWhenRecordedThenItIsReportedLikeTheOthers) {
  ConfigDocument doc = parse_ok("camera:\n  fx: -3\n");
  ConfigMap cam = doc.root().child("camera");
  double fx = 0;
  cam.require("fx", &fx);
  if (fx <= 0) cam.record_error("fx", "must be > 0, got " + std::to_string(fx));
  EXPECT_TRUE(contains(doc.finish().message(), "lab.yaml:2: key 'camera.fx': must be > 0"))
      << doc.finish().message();
}

TEST(Config, GivenFilesWhenLoadedThenSourceNameIsThePathAndMissingFileIsNotFound) {
  auto missing = ConfigDocument::load_file("/nonexistent/hwr/lab.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
  EXPECT_TRUE(contains(missing.status().message(), "/nonexistent/hwr/lab.yaml"));

  const std::string path = ::testing::TempDir() + "hwr_config_test.yaml";
  {
    std::ofstream f(path);
    f << "seed: 3\nextra: 1\n";
  }
  auto doc = ConfigDocument::load_file(path);
  ASSERT_TRUE(doc.ok()) << doc.status().to_string();
  EXPECT_EQ(doc->source_name(), path);
  int seed = 0;
  doc->root().get("seed", &seed);
  EXPECT_EQ(seed, 3);
  EXPECT_EQ(doc->finish().message(), path + ":2: unknown key 'extra'");
  std::remove(path.c_str());
}

}  // namespace
}  // namespace hwr::core
