// The robot's welding-region list and the operator's commands (detect/detection_ledger.hpp).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "hwr/detect/detection_ledger.hpp"

namespace {

using hwr::detect::CommandOutcome;
using hwr::detect::DetectionLedger;
using hwr::detect::DetectionState;
using hwr::detect::LedgerEntry;
using hwr::detect::OperatorCommand;
using hwr::detect::OperatorCommandKind;

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

LedgerEntry seen_at(double x, double y) {
  LedgerEntry e;
  e.confidence = 0.8f;
  e.keyframe_t_ns = 1'000;
  e.box_px = cv::Rect2f(10, 20, 30, 40);
  e.T_world_box = at(x, y, 0.9);
  e.half_size_m = Eigen::Vector3d(0.3, 0.15, 0.1);
  return e;
}

OperatorCommand command(int64_t id, OperatorCommandKind kind, int64_t detection) {
  OperatorCommand c;
  c.command_id = id;
  c.kind = kind;
  c.detection_id = detection;
  return c;
}

std::string temp_path(const char* name) {
  return ::testing::TempDir() + "ledger_" + std::to_string(::getpid()) + "_" + name;
}

TEST(DetectionLedger, GivenARegionSeenTwiceThenOneProposedEntryFollowsItsBox) {
  DetectionLedger ledger;
  const Eigen::Isometry3d T_map_world = at(10, 0, 0);
  const int64_t id = ledger.observe_region(7, seen_at(1, 2), T_map_world, 100);
  EXPECT_EQ(ledger.observe_region(7, seen_at(1.2, 2), T_map_world, 200), id);
  ASSERT_EQ(ledger.entries().size(), 1u);
  const LedgerEntry& e = ledger.entries()[0];
  EXPECT_EQ(e.state, DetectionState::kProposed);
  EXPECT_NEAR(e.T_map_box.translation().x(), 11.2, 1e-12);  // map frame = T_map_world * world
  EXPECT_EQ(ledger.find_region(7), &e);
  std::vector<int64_t> changed;
  ledger.take_changed(&changed);
  EXPECT_EQ(changed, std::vector<int64_t>{id});
  ledger.observe_region(7, seen_at(1.2, 2), T_map_world, 300);  // unchanged: nothing to publish
  ledger.take_changed(&changed);
  EXPECT_TRUE(changed.empty());
}

TEST(DetectionLedger, GivenARejectThenTheRegionStaysListedRejectedAndSuppressesDetectionsOnIt) {
  DetectionLedger ledger;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const int64_t id = ledger.observe_region(0, seen_at(1, 2), I, 100);
  EXPECT_FALSE(ledger.suppressed(at(1.1, 2, 0.9), Eigen::Vector3d(0.2, 0.1, 0.1)));
  const CommandOutcome o = ledger.apply(command(5, OperatorCommandKind::kReject, id), I, 200);
  EXPECT_TRUE(o.accepted) << o.reason;
  EXPECT_EQ(o.detection_id, id);
  EXPECT_EQ(ledger.find(id)->state, DetectionState::kRejected);
  EXPECT_TRUE(ledger.suppressed(at(1.1, 2, 0.9), Eigen::Vector3d(0.2, 0.1, 0.1)));
  EXPECT_FALSE(ledger.suppressed(at(3, 2, 0.9), Eigen::Vector3d(0.2, 0.1, 0.1)));
}

TEST(DetectionLedger, GivenTheSameCommandTwiceThenItIsAppliedOnceAndAnsweredAlike) {
  DetectionLedger ledger;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  OperatorCommand add = command(9, OperatorCommandKind::kAdd, -1);
  add.box_px = cv::Rect2f(100, 100, 50, 20);
  add.T_map_box = at(4, 4, 1);
  add.half_size_m = Eigen::Vector3d(0.2, 0.1, 0.05);
  bool repeated = true;
  const CommandOutcome first = ledger.apply(add, I, 10, &repeated);
  EXPECT_FALSE(repeated);
  ASSERT_TRUE(first.accepted) << first.reason;
  const CommandOutcome again = ledger.apply(add, I, 20, &repeated);
  EXPECT_TRUE(repeated);
  EXPECT_EQ(again.detection_id, first.detection_id);
  ASSERT_EQ(ledger.entries().size(), 1u);
  const LedgerEntry& e = ledger.entries()[0];
  EXPECT_EQ(e.source, hwr::detect::DetectionSource::kOperator);
  EXPECT_EQ(e.state, DetectionState::kConfirmed);
  EXPECT_TRUE(e.operator_box);
  EXPECT_EQ(ledger.commands().size(), 1u);
}

TEST(DetectionLedger, GivenBadCommandsThenEachIsRefusedWithItsReason) {
  DetectionLedger ledger;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const int64_t id = ledger.observe_region(0, seen_at(1, 2), I, 100);
  CommandOutcome o = ledger.apply(command(1, OperatorCommandKind::kConfirm, 99), I, 1);
  EXPECT_FALSE(o.accepted);
  EXPECT_EQ(o.reason, "no detection 99");
  OperatorCommand move = command(2, OperatorCommandKind::kMove, id);
  move.half_size_m = Eigen::Vector3d(0.1, -0.1, 0.1);
  o = ledger.apply(move, I, 1);
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.reason.find("move"), std::string::npos);
  OperatorCommand add = command(3, OperatorCommandKind::kAdd, -1);
  add.box_px = cv::Rect2f(1, 1, 10, 10);
  o = ledger.apply(add, I, 1);  // no 3D box
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.reason.find("no 3D box"), std::string::npos);
  o = ledger.apply(command(-4, OperatorCommandKind::kConfirm, id), I, 1);
  EXPECT_FALSE(o.accepted);
  EXPECT_EQ(ledger.find(id)->state, DetectionState::kProposed);
  EXPECT_EQ(ledger.entries().size(), 1u);
}

TEST(DetectionLedger, GivenAMovedBoxThenDetectionsNoLongerChangeIt) {
  DetectionLedger ledger;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const int64_t id = ledger.observe_region(3, seen_at(1, 2), I, 100);
  OperatorCommand move = command(4, OperatorCommandKind::kMove, id);
  move.T_map_box = at(1.5, 2, 0.9);
  move.half_size_m = Eigen::Vector3d(0.5, 0.2, 0.1);
  ASSERT_TRUE(ledger.apply(move, I, 200).accepted);
  ledger.observe_region(3, seen_at(0.5, 2), I, 300);
  EXPECT_NEAR(ledger.find(id)->T_map_box.translation().x(), 1.5, 1e-12);
  EXPECT_NEAR(ledger.find(id)->half_size_m.x(), 0.5, 1e-12);
}

TEST(DetectionLedger, GivenASavedLedgerThenLoadGivesItBackUnplacedUntilTheMapFrameIsKnown) {
  DetectionLedger ledger;
  const Eigen::Isometry3d T_map_world = at(5, 0, 0);
  const int64_t a = ledger.observe_region(0, seen_at(1, 2), T_map_world, 100);
  LedgerEntry with_seam = seen_at(3, 2);
  with_seam.has_seam = true;
  with_seam.seam_world = {Eigen::Vector3d(2.8, 2, 0.85), Eigen::Vector3d(3.2, 2, 0.85)};
  const int64_t b = ledger.observe_region(1, with_seam, T_map_world, 100);
  EXPECT_NEAR(ledger.find(b)->seam_map[1].x(), 8.2, 1e-12);  // map frame
  ASSERT_TRUE(ledger.apply(command(11, OperatorCommandKind::kReject, a), T_map_world, 200).accepted);
  CommandOutcome refused = ledger.apply(command(12, OperatorCommandKind::kConfirm, 42), T_map_world, 300);
  ASSERT_FALSE(refused.accepted);
  const std::string path = temp_path("saved.yaml");
  ASSERT_TRUE(ledger.save(path).ok());

  auto back = DetectionLedger::load(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->entries().size(), 2u);
  EXPECT_EQ(back->next_id(), ledger.next_id());
  EXPECT_EQ(back->find(a)->state, DetectionState::kRejected);
  EXPECT_EQ(back->find(b)->state, DetectionState::kProposed);
  EXPECT_NEAR(back->find(b)->T_map_box.translation().x(), 8.0, 1e-12);
  EXPECT_FALSE(back->find(a)->has_seam);
  ASSERT_TRUE(back->find(b)->has_seam);
  EXPECT_TRUE(back->find(b)->seam_map[0].isApprox(Eigen::Vector3d(7.8, 2, 0.85), 1e-15));
  EXPECT_EQ(back->find(a)->region_id, -1);
  ASSERT_EQ(back->commands().size(), 2u);
  EXPECT_EQ(back->commands()[1].reason, "no detection 42");
  // The same command id after the restart: answered from the journal, not applied again.
  bool repeated = false;
  EXPECT_FALSE(
      back->apply(command(12, OperatorCommandKind::kConfirm, b), T_map_world, 400, &repeated).accepted);
  EXPECT_TRUE(repeated);
  // Not placed: a rejected entry suppresses nothing until this run knows the map frame.
  EXPECT_FALSE(back->suppressed(at(1, 2, 0.9), Eigen::Vector3d(0.1, 0.1, 0.1)));
  std::vector<int64_t> placed;
  back->place(T_map_world, &placed, 500);
  EXPECT_EQ(placed.size(), 2u);
  EXPECT_TRUE(
      back->find(b)->seam_world[1].isApprox(Eigen::Vector3d(3.2, 2, 0.85), 1e-12));  // this run's world
  EXPECT_TRUE(back->suppressed(at(1, 2, 0.9), Eigen::Vector3d(0.1, 0.1, 0.1)));
  // New entries continue the numbering.
  EXPECT_EQ(back->observe_region(0, seen_at(7, 7), T_map_world, 600), ledger.next_id());
  std::filesystem::remove(path);
}

// Before relocalizing, the robot publishes in its own world: a region the operator draws then is in
// that frame, placed at once, and re-expressed in the prior's frame once the robot knows it.
TEST(DetectionLedger, GivenAnAddBeforeTheMapFrameIsKnownThenItIsPlacedInTheFrameOfTheMoment) {
  DetectionLedger ledger;
  OperatorCommand add = command(1, OperatorCommandKind::kAdd, -1);
  add.box_px = cv::Rect2f(10, 10, 20, 20);
  add.T_map_box = at(2, 0, 0);
  add.half_size_m = Eigen::Vector3d(0.1, 0.1, 0.1);
  const CommandOutcome o = ledger.apply(add, Eigen::Isometry3d::Identity(), 10);
  ASSERT_TRUE(o.accepted) << o.reason;
  EXPECT_TRUE(ledger.find(o.detection_id)->placed);
  std::vector<int64_t> placed;
  ledger.place(at(100, 0, 0), &placed, 20);  // relocalized: T_map_world = T_prior_world
  EXPECT_TRUE(placed.empty());
  EXPECT_NEAR(ledger.find(o.detection_id)->T_map_box.translation().x(), 102.0, 1e-12);
  EXPECT_NEAR(ledger.find(o.detection_id)->T_world_box.translation().x(), 2.0, 1e-12);
}

// A replayed or rebooted robot's clock starts again: every change is still stamped after the saved ones,
// so the ground station (which keeps the latest version) takes it.
TEST(DetectionLedger, GivenALoadedLedgerThenLaterChangesAreStampedAfterItsNewestChange) {
  DetectionLedger ledger;
  const int64_t id = ledger.observe_region(0, seen_at(1, 2), Eigen::Isometry3d::Identity(), 5'000);
  const std::string path = temp_path("stamps.yaml");
  ASSERT_TRUE(ledger.save(path).ok());
  auto back = DetectionLedger::load(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_TRUE(
      back->apply(command(3, OperatorCommandKind::kConfirm, id), Eigen::Isometry3d::Identity(), 7).accepted);
  EXPECT_EQ(back->find(id)->updated_t_ns, 5'001);
  LedgerEntry dropped;
  ASSERT_TRUE(back->drop(id, 8, &dropped));
  EXPECT_EQ(dropped.state, DetectionState::kRejected);
  EXPECT_EQ(dropped.updated_t_ns, 5'002);
  EXPECT_EQ(back->find(id), nullptr);
  EXPECT_FALSE(back->drop(id, 9, &dropped));
  std::filesystem::remove(path);
}

// A restored entry keeps its seam until this run fuses one of its own.
TEST(DetectionLedger, GivenARegionSeenWithoutASeamThenTheSeamItHadStays) {
  DetectionLedger ledger;
  LedgerEntry seen = seen_at(1, 2);
  seen.has_seam = true;
  seen.seam_world = {Eigen::Vector3d(0.8, 2, 0.9), Eigen::Vector3d(1.2, 2, 0.9)};
  const int64_t id = ledger.observe_region(0, seen, Eigen::Isometry3d::Identity(), 1);
  ledger.observe_region(0, seen_at(1.1, 2), Eigen::Isometry3d::Identity(), 2);
  ASSERT_TRUE(ledger.find(id)->has_seam);
  EXPECT_NEAR(ledger.find(id)->seam_map[1].x(), 1.2, 1e-12);
  EXPECT_NEAR(ledger.find(id)->T_map_box.translation().x(), 1.1, 1e-12);
}

TEST(DetectionLedger, GivenAnEmptyLedgerThenItSavesAndLoadsBackEmpty) {
  const std::string path = temp_path("empty.yaml");
  ASSERT_TRUE(DetectionLedger().save(path).ok());
  auto back = DetectionLedger::load(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_TRUE(back->entries().empty());
  EXPECT_TRUE(back->commands().empty());
  EXPECT_EQ(back->next_id(), 0);
  std::filesystem::remove(path);
}

TEST(DetectionLedger, GivenAMissingOrMalformedFileThenLoadSaysWhat) {
  auto missing = DetectionLedger::load(temp_path("absent.yaml"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), hwr::core::ErrorCode::kNotFound);

  DetectionLedger ledger;
  ledger.observe_region(0, seen_at(1, 2), Eigen::Isometry3d::Identity(), 100);
  const std::string good = ledger.to_yaml();
  const std::string path = temp_path("bad.yaml");
  auto load_text = [&](const std::string& text) {
    std::ofstream(path) << text;
    return DetectionLedger::load(path);
  };
  auto bad_state = load_text(std::string(good).replace(good.find("proposed"), 8, "maybe"));
  ASSERT_FALSE(bad_state.ok());
  EXPECT_NE(bad_state.status().message().find("state"), std::string::npos) << bad_state.status().message();
  auto truncated = load_text(good.substr(0, good.find("half_size_m")));
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.status().message().find("half_size_m"), std::string::npos)
      << truncated.status().message();
  auto garbage = load_text("\x01\x02 [[[ not yaml");
  EXPECT_FALSE(garbage.ok());
  // Every cut of the file is either the ledger or an error, never a crash.
  for (size_t n = 0; n < good.size(); n += 7) (void)load_text(good.substr(0, n));
  std::filesystem::remove(path);
}

}  // namespace
