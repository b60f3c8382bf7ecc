// The ground station's operator console (mapio/operator_console.hpp): the detection list it keeps
// (the latest run, then the newest t_ns wins), commands persisted as pending and re-published until an ack
// arrives, acks matched once, everything restored after the console is destroyed and reopened on the same
// folder, damaged files set aside with a note, and a whole operator round trip over LCM's memq:// transport
// against a minimal robot written here (the real one is hwr-robot's MapStreamer).

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "hwr/core/file_io.hpp"
#include "hwr/mapio/ground_store.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/operator_console.hpp"
#include "operator_fakes.hpp"
#include "temp_dir.hpp"

namespace hwr::mapio {
namespace {

namespace fs = std::filesystem;
using core::ErrorCode;
using hwr::testing::TempDir;
using test::FakeRobot;
using test::kMs;
using test::make_ack;
using test::make_command;
using test::make_detection;

template <class Msg>
std::vector<uint8_t> encoded(const Msg& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

void give(OperatorConsole& c, const hwr_lcm::detection_t& d) {
  const auto b = encoded(d);
  c.on_detection_message(b.data(), b.size(), 0);
}
void give(OperatorConsole& c, const hwr_lcm::command_ack_t& a) {
  const auto b = encoded(a);
  c.on_ack_message(b.data(), b.size(), 0);
}

std::unique_ptr<OperatorConsole> open_ok(const std::string& dir) {
  auto c = OperatorConsole::open(dir);
  EXPECT_TRUE(c.ok()) << c.status().message();
  return c.ok() ? std::move(c.value()) : nullptr;
}

std::string read_text(const std::string& path) {
  std::string s;
  EXPECT_TRUE(core::read_file(path, &s).ok()) << path;
  return s;
}

std::vector<std::string> data_lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != '#') out.push_back(line);
  }
  return out;
}

std::vector<int64_t> ids_of(const std::vector<hwr_lcm::detection_t>& ds) {
  std::vector<int64_t> out;
  for (const auto& d : ds) out.push_back(d.detection_id);
  return out;
}

std::set<std::string> names_in(const std::string& dir) {
  std::set<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.insert(e.path().filename().string());
  return out;
}

// Publishes through service() and returns the command_ids published.
std::vector<int64_t> service_ids(OperatorConsole& c, int64_t now_ns) {
  std::vector<int64_t> out;
  c.service(now_ns, [&](const hwr_lcm::operator_command_t& cmd) { out.push_back(cmd.command_id); });
  return out;
}

// --- detections ------------------------------------------------------------------------------------

TEST(OperatorConsole, GivenDetectionsThenListSortedByIdStoredAndListed) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  for (const int64_t id : {4, 2, 9}) give(*c, make_detection(id, 1000 + id));
  EXPECT_EQ(ids_of(c->detections("hwr-0")), (std::vector<int64_t>{2, 4, 9}));
  EXPECT_EQ(c->robots_with_detections(), (std::vector<std::string>{"hwr-0"}));
  EXPECT_EQ(c->robots(), (std::vector<std::string>{"hwr-0"}));
  EXPECT_TRUE(c->detections("other").empty());
  EXPECT_EQ(c->stats().detections_updated, 3);
  const std::string dir = c->operator_dir("hwr-0");
  EXPECT_EQ(dir, tmp.file("out") + "/hwr-0/operator");
  EXPECT_EQ(names_in(dir + "/detections"),
            (std::set<std::string>{"detection_2.lcm", "detection_4.lcm", "detection_9.lcm"}));
  const auto lines = data_lines(read_text(dir + "/detections.txt"));
  ASSERT_EQ(lines.size(), 3u);
  // Detection 4: centre x 1.25 + 4, seam from x 1.05 + 4 to 1.45 + 4.
  EXPECT_EQ(
      lines[1],
      "4 geometry proposed 0.750 5.2500 -0.5000 0.7500 0.4000 0.0500 0.0500 5.0500 -0.5000 0.7000 5.4500 "
      "-0.5000 0.7000 1732477000100000000 1004");
}

TEST(OperatorConsole, GivenNewerAndOlderVersionsThenNewestTnsWins) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  give(*c, make_detection(4, 2000, 0));
  give(*c, make_detection(4, 3000, 1));  // newer: confirmed
  give(*c, make_detection(4, 2500, 2));  // older, reordered: ignored
  give(*c, make_detection(4, 3000, 2));  // same t_ns: a repeat, ignored
  const hwr_lcm::detection_t* d = c->find_detection("hwr-0", 4);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->state, 1);
  EXPECT_EQ(d->t_ns, 3000);
  EXPECT_EQ(c->stats().detections_updated, 2);
  EXPECT_EQ(c->stats().detections_ignored, 2);
  EXPECT_NE(read_text(c->operator_dir("hwr-0") + "/detections.txt").find("4 geometry confirmed"),
            std::string::npos);
}

TEST(OperatorConsole, GivenALaterRunWithEarlierTimestampsThenItsDetectionReplacesTheEarlierRuns) {
  // A replayed or simulated run starts its clock where the last one did: its t_ns repeat, its run_id
  // (the start time) is later. Its detection 4 is another region and must replace run 1's.
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  hwr_lcm::detection_t first = make_detection(4, 3000, 1);
  first.run_id = 100;
  give(*c, first);
  hwr_lcm::detection_t later_run = make_detection(4, 2000, 0);
  later_run.run_id = 200;
  give(*c, later_run);
  hwr_lcm::detection_t late_from_the_first = make_detection(4, 5000, 2);
  late_from_the_first.run_id = 100;
  give(*c, late_from_the_first);  // an earlier run's message arriving late: ignored
  const hwr_lcm::detection_t* d = c->find_detection("hwr-0", 4);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->run_id, 200);
  EXPECT_EQ(d->t_ns, 2000);
  EXPECT_EQ(d->state, 0);
  EXPECT_EQ(c->stats().detections_ignored, 1);
}

TEST(OperatorConsole, GivenUndecodableOrInvalidMessagesThenRejectedAndNothingStored) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  const std::vector<uint8_t> garbage(40, 0xAB);
  c->on_detection_message(garbage.data(), garbage.size(), 0);
  c->on_ack_message(garbage.data(), garbage.size(), 0);
  hwr_lcm::detection_t bad = make_detection(1, 10);
  bad.confidence = 2;
  give(*c, bad);
  hwr_lcm::detection_t hostile = make_detection(1, 10, 0, "../etc");
  give(*c, hostile);
  EXPECT_EQ(c->stats().messages, 4);
  EXPECT_EQ(c->stats().rejected, 4);
  EXPECT_NE(c->stats().last_error.find("robot_id"), std::string::npos) << c->stats().last_error;
  EXPECT_TRUE(c->robots().empty());
  EXPECT_EQ(names_in(tmp.file("out")), (std::set<std::string>{".operator_console.lock"}));
}

TEST(OperatorConsole, GivenLimitsThenNewRobotsAndDetectionsBeyondThemRefused) {
  TempDir tmp;
  OperatorConsoleConfig config;
  config.out_dir = tmp.file("out");
  config.max_robots = 1;
  config.max_detections_per_robot = 2;
  auto opened = OperatorConsole::open(config);
  ASSERT_TRUE(opened.ok());
  OperatorConsole& c = *opened.value();
  give(c, make_detection(1, 10));
  give(c, make_detection(2, 10));
  give(c, make_detection(3, 10));              // a third id
  give(c, make_detection(1, 20, 1));           // a known id still updates
  give(c, make_detection(1, 10, 0, "hwr-1"));  // a second robot
  EXPECT_EQ(ids_of(c.detections("hwr-0")), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(c.find_detection("hwr-0", 1)->state, 1);
  EXPECT_EQ(c.stats().detections_refused, 2);
  EXPECT_EQ(c.robots(), (std::vector<std::string>{"hwr-0"}));
  EXPECT_EQ(c.send(make_command(OperatorCommandKind::kReject, 1, "hwr-1")).status().code(),
            ErrorCode::kUnavailable);
}

// --- commands --------------------------------------------------------------------------------------

TEST(OperatorConsole, GivenCommandWhenServicedThenResentEveryIntervalUntilAckedOnce) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  give(*c, make_detection(4, 1000));
  auto id = c->send(make_command(OperatorCommandKind::kReject, 4));
  ASSERT_TRUE(id.ok()) << id.status().message();
  EXPECT_GT(*id, 0);
  EXPECT_EQ(c->command(*id)->state, CommandState::kPending);
  EXPECT_EQ(c->pending_commands(), 1);

  const int64_t t0 = 5'000 * kMs;
  EXPECT_EQ(service_ids(*c, t0), (std::vector<int64_t>{*id}));  // first publish at once
  EXPECT_TRUE(service_ids(*c, t0 + 499 * kMs).empty());         // within resend_interval_ns (500 ms)
  EXPECT_EQ(service_ids(*c, t0 + 500 * kMs), (std::vector<int64_t>{*id}));
  EXPECT_TRUE(service_ids(*c, t0 + 900 * kMs).empty());
  EXPECT_EQ(service_ids(*c, t0 + 1000 * kMs), (std::vector<int64_t>{*id}));
  EXPECT_EQ(c->stats().publishes, 3);
  EXPECT_EQ(c->stats().commands_resent, 2);
  EXPECT_EQ(c->command(*id)->publishes, 3);

  give(*c, make_ack(*id, true, 4));
  auto r = c->command(*id);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->state, CommandState::kAccepted);
  EXPECT_EQ(r->detection_id, 4);
  EXPECT_EQ(c->pending_commands(), 0);
  EXPECT_TRUE(service_ids(*c, t0 + 10'000 * kMs).empty());

  // The robot re-acknowledges the resend that crossed our ack; a contradicting one changes nothing.
  give(*c, make_ack(*id, true, 4));
  give(*c, make_ack(*id, false, 4, "late"));
  EXPECT_EQ(c->stats().commands_acked, 1);
  EXPECT_EQ(c->stats().duplicate_acks, 2);
  EXPECT_EQ(c->command(*id)->state, CommandState::kAccepted);
  const auto acked = c->take_acknowledged();
  ASSERT_EQ(acked.size(), 1u);
  EXPECT_EQ(acked[0].command.command_id, *id);
  EXPECT_TRUE(c->take_acknowledged().empty());
}

TEST(OperatorConsole, GivenRefusedAckThenReasonKeptAndJournaled) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  auto id = c->send(make_command(OperatorCommandKind::kConfirm, 12));
  ASSERT_TRUE(id.ok());
  give(*c, make_ack(*id, false, 12, "no detection 12\non this robot"));
  const auto r = c->command(*id);
  EXPECT_EQ(r->state, CommandState::kRefused);
  EXPECT_EQ(r->reason, "no detection 12\non this robot");
  const std::string journal = read_text(c->operator_dir("hwr-0") + "/journal.log");
  const auto lines = data_lines(journal);
  ASSERT_EQ(lines.size(), 2u) << journal;
  const std::string id_text = std::to_string(*id);
  EXPECT_NE(lines[0].find("command " + id_text + " (confirm 12): sent"), std::string::npos) << lines[0];
  EXPECT_NE(lines[1].find("command " + id_text + " (confirm 12): refused: no detection 12 on this robot"),
            std::string::npos)
      << lines[1];
  // UTC time first: "YYYY-MM-DDThh:mm:ss.mmmZ ".
  EXPECT_EQ(lines[0].size() > 25 ? lines[0].substr(23, 2) : "", "Z ") << lines[0];
}

TEST(OperatorConsole, GivenAcksForNoCommandOfOursThenCountedAsUnmatched) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  auto id = c->send(make_command(OperatorCommandKind::kReject, 1));
  ASSERT_TRUE(id.ok());
  give(*c, make_ack(*id + 1000, true, 1));            // another ground station's command
  give(*c, make_ack(*id, true, 1, "", "hwr-other"));  // our id, but from another robot
  EXPECT_EQ(c->stats().unmatched_acks, 2);
  EXPECT_EQ(c->command(*id)->state, CommandState::kPending);
  EXPECT_EQ(c->command(*id + 1000).status().code(), ErrorCode::kNotFound);
}

TEST(OperatorConsole, GivenMalformedCommandsThenSendRefusesAndStoresNothing) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  auto no_robot = make_command(OperatorCommandKind::kReject, 1, "");
  EXPECT_EQ(c->send(no_robot).status().code(), ErrorCode::kOutOfRange);
  auto bad_kind = make_command(OperatorCommandKind::kReject, 1);
  bad_kind.kind = 7;
  EXPECT_EQ(c->send(bad_kind).status().code(), ErrorCode::kOutOfRange);
  auto no_target = make_command(OperatorCommandKind::kConfirm, -1);
  EXPECT_EQ(c->send(no_target).status().code(), ErrorCode::kOutOfRange);
  auto flat_move = make_command(OperatorCommandKind::kMove, 1);
  flat_move.box_size_m[2] = 0;
  const auto st = c->send(flat_move).status();
  EXPECT_EQ(st.code(), ErrorCode::kOutOfRange);
  EXPECT_NE(st.message().find("box_size_m"), std::string::npos) << st.message();
  auto tilted = make_command(OperatorCommandKind::kMove, 1);
  tilted.box_q_world_box[0] = 0.9;
  EXPECT_EQ(c->send(tilted).status().code(), ErrorCode::kInvalidArgument);
  auto empty_add = make_command(OperatorCommandKind::kAdd, 0);
  empty_add.box_px[3] = 0;
  EXPECT_EQ(c->send(empty_add).status().code(), ErrorCode::kOutOfRange);
  auto path_robot = make_command(OperatorCommandKind::kReject, 1, "a/../b");
  EXPECT_EQ(c->send(path_robot).status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(c->stats().commands_sent, 0);
  EXPECT_EQ(names_in(tmp.file("out")), (std::set<std::string>{".operator_console.lock"}));
}

TEST(OperatorConsole, GivenIgnoredFieldsHoldingGarbageThenSendClearsThem) {
  TempDir tmp;
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  auto id = c->send(make_command(OperatorCommandKind::kReject, 3));  // box fields are NaN patterns
  ASSERT_TRUE(id.ok()) << id.status().message();
  const hwr_lcm::operator_command_t sent = c->command(*id)->command;
  EXPECT_EQ(sent.keyframe_t_ns, 0);
  for (const float v : sent.box_px) EXPECT_EQ(v, 0.f);
  for (const double v : sent.box_size_m) EXPECT_EQ(v, 0.0);
  EXPECT_EQ(sent.box_q_world_box[0], 1.0);
  auto add = c->send(make_command(OperatorCommandKind::kAdd, 55));
  ASSERT_TRUE(add.ok()) << add.status().message();
  EXPECT_EQ(c->command(*add)->command.detection_id, -1);  // add ignores it
  EXPECT_EQ(c->command(*add)->command.keyframe_t_ns, 1732477000100000000);
}

TEST(OperatorConsole, GivenManySendsAndReopensThenCommandIdsStrictlyIncrease) {
  TempDir tmp;
  int64_t last = 0;
  for (int session = 0; session < 3; ++session) {
    auto c = open_ok(tmp.file("out"));
    ASSERT_TRUE(c);
    for (int i = 0; i < 20; ++i) {
      const std::string robot = i % 2 == 0 ? "hwr-0" : "hwr-1";  // one sequence for every robot
      auto id = c->send(make_command(OperatorCommandKind::kConfirm, i, robot));
      ASSERT_TRUE(id.ok());
      EXPECT_GT(*id, last);
      last = *id;
    }
  }
}

TEST(OperatorConsole, GivenStoredIdAheadOfTheClockThenNextIdIsAboveIt) {
  TempDir tmp;
  const int64_t future = int64_t{4'000'000'000} * 1'000'000'000;  // year 2096
  {
    auto c = open_ok(tmp.file("out"));
    ASSERT_TRUE(c);
    ASSERT_TRUE(c->send(make_command(OperatorCommandKind::kConfirm, 1)).ok());
    // As if this ground station's clock had run ahead and was set back: a stored id in the future.
    hwr_lcm::operator_command_t ahead = c->commands("hwr-0")[0].command;
    ahead.command_id = future;
    const auto b = encoded(ahead);
    ASSERT_TRUE(core::write_file_atomic(
                    c->operator_dir("hwr-0") + "/commands/command_" + std::to_string(future) + ".lcm", b)
                    .ok());
  }
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  auto id = c->send(make_command(OperatorCommandKind::kConfirm, 2));
  ASSERT_TRUE(id.ok());
  EXPECT_EQ(*id, future + 1);
}

// --- restarts --------------------------------------------------------------------------------------

TEST(OperatorConsole, GivenRestartThenListAndCommandsSurviveAndPendingOnesAreResent) {
  TempDir tmp;
  int64_t acked = 0, pending = 0, refused = 0;
  {
    auto c = open_ok(tmp.file("out"));
    ASSERT_TRUE(c);
    for (const int64_t id : {1, 2, 3}) give(*c, make_detection(id, 100 + id));
    give(*c, make_detection(2, 500, 2));
    acked = *c->send(make_command(OperatorCommandKind::kReject, 2));
    refused = *c->send(make_command(OperatorCommandKind::kConfirm, 9));
    pending = *c->send(make_command(OperatorCommandKind::kAdd, 0));
    EXPECT_EQ(service_ids(*c, 0).size(), 3u);
    give(*c, make_ack(acked, true, 2));
    give(*c, make_ack(refused, false, 9, "no detection 9"));
  }
  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  const auto& report = c->open_report();
  EXPECT_EQ(report.detections_loaded, 3);
  EXPECT_EQ(report.commands_loaded, 3);
  EXPECT_EQ(report.commands_pending, 1);
  EXPECT_TRUE(report.notes.empty()) << report.notes.front();
  EXPECT_EQ(ids_of(c->detections("hwr-0")), (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(c->find_detection("hwr-0", 2)->state, 2);
  EXPECT_EQ(c->find_detection("hwr-0", 2)->t_ns, 500);
  EXPECT_EQ(c->command(acked)->state, CommandState::kAccepted);
  EXPECT_EQ(c->command(refused)->state, CommandState::kRefused);
  EXPECT_EQ(c->command(refused)->reason, "no detection 9");
  EXPECT_EQ(c->command(pending)->state, CommandState::kPending);
  EXPECT_EQ(c->commands("hwr-0").size(), 3u);
  // Re-sent at once after the restart, then on the interval again.
  EXPECT_EQ(service_ids(*c, 0), (std::vector<int64_t>{pending}));
  EXPECT_EQ(service_ids(*c, 500 * kMs), (std::vector<int64_t>{pending}));
  give(*c, make_ack(pending, true, 4));
  EXPECT_EQ(c->command(pending)->detection_id, 4);
  // An older detection still loses to the restored one.
  give(*c, make_detection(2, 400, 0));
  EXPECT_EQ(c->find_detection("hwr-0", 2)->state, 2);
}

TEST(OperatorConsole, GivenSecondConsoleOnTheSameFolderThenUnavailable) {
  TempDir tmp;
  auto first = open_ok(tmp.file("out"));
  ASSERT_TRUE(first);
  auto second = OperatorConsole::open(tmp.file("out"));
  EXPECT_EQ(second.status().code(), ErrorCode::kUnavailable);
  first.reset();
  EXPECT_TRUE(OperatorConsole::open(tmp.file("out")).ok());
}

TEST(OperatorConsole, GivenDamagedFilesThenSetAsideWithNotesAndTheRestLoads) {
  TempDir tmp;
  int64_t cmd_a = 0, cmd_b = 0;
  std::string dir;
  {
    auto c = open_ok(tmp.file("out"));
    ASSERT_TRUE(c);
    for (const int64_t id : {1, 2, 3}) give(*c, make_detection(id, 100));
    cmd_a = *c->send(make_command(OperatorCommandKind::kReject, 1));
    cmd_b = *c->send(make_command(OperatorCommandKind::kReject, 2));
    give(*c, make_ack(cmd_a, true, 1));
    give(*c, make_ack(cmd_b, true, 2));
    dir = c->operator_dir("hwr-0");
  }
  // Detection 1: bit rot. Detection 2: another detection's bytes under its name. Command a: cut
  // short. Ack b: garbage (b is pending again). Plus an interrupted write and a stray file.
  std::string bytes = read_text(dir + "/detections/detection_1.lcm");
  bytes[bytes.size() / 2] ^= 0x40;
  bytes.push_back('x');
  ASSERT_TRUE(core::write_file_atomic(dir + "/detections/detection_1.lcm", bytes).ok());
  fs::copy_file(dir + "/detections/detection_3.lcm", dir + "/detections/detection_2.lcm",
                fs::copy_options::overwrite_existing);
  const std::string cmd_a_path = dir + "/commands/command_" + std::to_string(cmd_a) + ".lcm";
  bytes = read_text(cmd_a_path);
  ASSERT_TRUE(core::write_file_atomic(cmd_a_path, bytes.substr(0, bytes.size() - 3)).ok());
  ASSERT_TRUE(core::write_file_atomic(dir + "/commands/ack_" + std::to_string(cmd_b) + ".lcm",
                                      std::string(5000, '\x7f'))
                  .ok());
  ASSERT_TRUE(core::write_file_atomic(dir + "/detections/detection_7.lcm.tmp", std::string("half")).ok());
  ASSERT_TRUE(core::write_file_atomic(dir + "/commands/notes.txt", std::string("an operator's file")).ok());

  auto c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  const auto& r = c->open_report();
  EXPECT_EQ(r.corrupt_set_aside, 4);
  EXPECT_EQ(r.temp_files_removed, 1);
  std::string notes;
  for (const auto& n : r.notes) notes += n + "\n";
  EXPECT_NE(notes.find("detection_1.lcm: detection_t"), std::string::npos) << notes;
  EXPECT_NE(notes.find("detection_2.lcm: the message names robot hwr-0 detection 3"), std::string::npos)
      << notes;
  EXPECT_NE(notes.find("truncated"), std::string::npos) << notes;
  EXPECT_NE(
      notes.find("ack_" + std::to_string(cmd_a) + ".lcm: acknowledgement of a command that is not stored"),
      std::string::npos)
      << notes;
  EXPECT_NE(notes.find("notes.txt: not an operator file, ignored"), std::string::npos) << notes;
  EXPECT_EQ(ids_of(c->detections("hwr-0")), (std::vector<int64_t>{3}));
  EXPECT_EQ(c->command(cmd_a).status().code(), ErrorCode::kNotFound);
  EXPECT_EQ(c->command(cmd_b)->state, CommandState::kPending);
  EXPECT_EQ(service_ids(*c, 0), (std::vector<int64_t>{cmd_b}));
  EXPECT_TRUE(fs::exists(dir + "/detections/detection_1.lcm.corrupt"));
  EXPECT_FALSE(fs::exists(dir + "/detections/detection_7.lcm.tmp"));
  // The listing was rewritten from what loaded.
  EXPECT_EQ(data_lines(read_text(dir + "/detections.txt")).size(), 1u);
  // Set aside once: a second reopen finds nothing new to report but the stray file and the orphan ack.
  c.reset();
  c = open_ok(tmp.file("out"));
  ASSERT_TRUE(c);
  EXPECT_EQ(c->open_report().corrupt_set_aside, 0);
}

TEST(OperatorConsole, GivenOperatorFilesBesideTheGroundStoreThenTheStoreLeavesThemAlone) {
  TempDir tmp;
  {
    auto c = open_ok(tmp.file("out"));
    ASSERT_TRUE(c);
    give(*c, make_detection(1, 100));
    auto store = GroundStore::open(tmp.file("out"));  // both open at once, as in hwr-ground
    ASSERT_TRUE(store.ok()) << store.status().message();
    EXPECT_TRUE(store->open_report().notes.empty()) << store->open_report().notes.front();
    EXPECT_TRUE(store->runs().empty());
  }
}

// --- over LCM ---------------------------------------------------------------------------------------

void wire(LcmLink* link, OperatorConsole** console) {
  link->subscribe(kChannelDetection,
                  [console](const uint8_t* d, size_t n) { (*console)->on_detection_message(d, n, 0); });
  link->subscribe(kChannelOperatorAck,
                  [console](const uint8_t* d, size_t n) { (*console)->on_ack_message(d, n, 0); });
}

void pump(LcmLink* link, OperatorConsole* console, int64_t now_ns) {
  console->service(now_ns, [&](const hwr_lcm::operator_command_t& c) {
    ASSERT_TRUE(link->publish(kChannelOperatorCommand, c).ok());
  });
  for (int i = 0; i < 20; ++i) {
    auto n = link->drain();
    ASSERT_TRUE(n.ok());
    if (*n == 0) break;
  }
}

TEST(OperatorConsole, GivenMemqLinkWhenRejectAndAddThenRobotListChangesAndSurvivesRestartOfBothEnds) {
  TempDir tmp;
  auto opened = LcmLink::open("memq://");
  ASSERT_TRUE(opened.ok()) << opened.status().message();
  LcmLink& link = opened.value();
  OperatorConsole* console_ptr = nullptr;
  wire(&link, &console_ptr);
  auto robot = std::make_unique<FakeRobot>(&link);
  for (const int64_t id : {0, 1, 2}) robot->detections[id] = make_detection(id, 100);

  int64_t reject_id = 0, add_id = 0;
  {
    auto console = open_ok(tmp.file("out"));
    ASSERT_TRUE(console);
    console_ptr = console.get();
    robot->publish_all();
    pump(&link, console_ptr, 0);
    ASSERT_EQ(ids_of(console->detections("hwr-0")), (std::vector<int64_t>{0, 1, 2}));

    robot->drop_acks = true;  // the first acks are lost: the console must resend
    reject_id = *console->send(make_command(OperatorCommandKind::kReject, 1));
    add_id = *console->send(make_command(OperatorCommandKind::kAdd, 0));
    pump(&link, console_ptr, 1000 * kMs);
    EXPECT_EQ(console->pending_commands(), 2);
    robot->drop_acks = false;
    pump(&link, console_ptr, 1500 * kMs);
    EXPECT_EQ(console->pending_commands(), 0);
    EXPECT_EQ(robot->commands_received, 4);  // each command twice, applied once
    console_ptr = nullptr;
  }
  // Both ends restart: the robot keeps its ledger (its own store), the console its folder.
  const auto ledger = robot->detections;
  robot.reset();  // nothing is dispatched on this link from here on (its handler would be dangling)
  ASSERT_EQ(ledger.size(), 4u);
  EXPECT_EQ(ledger.at(1).state, 2);
  EXPECT_EQ(ledger.at(3).source, 2);
  auto console = open_ok(tmp.file("out"));
  ASSERT_TRUE(console);
  console_ptr = console.get();
  std::vector<int64_t> states;
  for (const auto& d : console->detections("hwr-0")) states.push_back(d.state);
  EXPECT_EQ(ids_of(console->detections("hwr-0")), (std::vector<int64_t>{0, 1, 2, 3}));
  EXPECT_EQ(states, (std::vector<int64_t>{0, 2, 0, 1}));
  EXPECT_EQ(console->command(reject_id)->state, CommandState::kAccepted);
  EXPECT_EQ(console->command(add_id)->detection_id, 3);
  EXPECT_EQ(console->find_detection("hwr-0", 3)->box_px[2], 30.f);
  console_ptr = nullptr;
}

}  // namespace
}  // namespace hwr::mapio
