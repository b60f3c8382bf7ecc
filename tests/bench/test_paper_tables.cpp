// bench/paper_tables: the key=value parsing and the cells and tables `hwr-bench paper` builds from it.

#include "paper_tables.hpp"

#include <cmath>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace hwr::bench::paper {
namespace {

RunResult ok_run(const std::string& stdout_text) {
  RunResult r;
  r.id = "frame";
  r.ran = r.ok = true;
  r.exit_code = 0;
  r.keys = parse_key_values(stdout_text);
  return r;
}

size_t code_points(const std::string& s) {
  size_t n = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++n;
  return n;
}

TEST(PaperKeyValues, AcceptsTheBenchesKeyLines) {
  std::string k, v;
  ASSERT_TRUE(parse_key_value_line("frame_ms_mean_teddy=7.582", &k, &v));
  EXPECT_EQ(k, "frame_ms_mean_teddy");
  EXPECT_EQ(v, "7.582");
  ASSERT_TRUE(parse_key_value_line("ndt_ms_room-synth=12.5\r", &k, &v));  // ndt's dataset names have '-'
  EXPECT_EQ(k, "ndt_ms_room-synth");
  EXPECT_EQ(v, "12.5");
  ASSERT_TRUE(parse_key_value_line("plates_seen_lab=18/18", &k, &v));
  EXPECT_EQ(v, "18/18");
  ASSERT_TRUE(parse_key_value_line("latency_s_ours_1000mbit_0.1m=0.0190", &k, &v));
  EXPECT_EQ(k, "latency_s_ours_1000mbit_0.1m");
  ASSERT_TRUE(parse_key_value_line("empty=", &k, &v));
  EXPECT_EQ(v, "");
}

TEST(PaperKeyValues, RejectsHumanLines) {
  std::string k, v;
  for (const char* line :
       {"ATE without segmentation 0.0165 m, with 0.0148 m", "a b=3", "=3", "key=a b", "1abc=2", "  key=3",
        "sequence  method  frames", "reloc: lab start 3/10 (2 s)", ""}) {
    EXPECT_FALSE(parse_key_value_line(line, &k, &v)) << line;
  }
}

TEST(PaperKeyValues, TheLastValueOfAKeyWins) {
  const KeyValues kv = parse_key_values(
      "sequence method\nteddy hwr 7.58\nate_m_teddy=0.00446\nnote: x = "
      "3\nate_m_teddy=0.00450\nframe_ms_p99=13.2\n");
  ASSERT_EQ(kv.lines.size(), 3u);
  ASSERT_NE(kv.find("ate_m_teddy"), nullptr);
  EXPECT_EQ(*kv.find("ate_m_teddy"), "0.00450");
  EXPECT_EQ(kv.find("missing"), nullptr);
}

TEST(PaperKeyValues, NumbersAreWholeTexts) {
  EXPECT_DOUBLE_EQ(*to_number("7.582"), 7.582);
  EXPECT_DOUBLE_EQ(*to_number("-0.3"), -0.3);
  EXPECT_DOUBLE_EQ(*to_number("1e-3"), 1e-3);
  EXPECT_TRUE(std::isnan(*to_number("nan")));
  EXPECT_FALSE(to_number("18/18").has_value());
  EXPECT_FALSE(to_number("pcl-1.13").has_value());
  EXPECT_FALSE(to_number("").has_value());
}

TEST(PaperCells, ARunCellIsTheKeyAsPrinted) {
  const RunResult run = ok_run("frame_ms_mean_teddy=7.582\nframe_ms_sd_teddy=2.100\nate_m_teddy=0.00446\n");
  const Cell c = run_cell(run, "ate_m_teddy", "paper_t1_ours_ate_m_teddy");
  EXPECT_TRUE(c.available);
  EXPECT_EQ(c.text, "0.00446");
  EXPECT_EQ(c.value_text, "0.00446");
  EXPECT_DOUBLE_EQ(c.value, 0.00446);
  EXPECT_EQ(c.source, "frame: ate_m_teddy");
  const Cell m = run_mean_sd_cell(run, "frame_ms_mean_teddy", "frame_ms_sd_teddy", "k");
  EXPECT_EQ(m.text, "7.582 ± 2.100");
  EXPECT_DOUBLE_EQ(m.value, 7.582);
  EXPECT_EQ(m.source, "frame: frame_ms_mean_teddy ± frame_ms_sd_teddy");
}

TEST(PaperCells, NotAvailableSaysWhy) {
  RunResult failed = ok_run("ate_m_teddy=0.00446\n");
  failed.ok = false;
  failed.why_not = "exit code 1";
  const Cell a = run_cell(failed, "ate_m_teddy", "paper_x");
  EXPECT_FALSE(a.available);
  EXPECT_EQ(a.text, "n/a (frame: exit code 1)");  // a failed run's keys are not used
  EXPECT_EQ(a.value_text, "nan");
  const Cell b = run_cell(ok_run("ate_m_teddy=0.00446\n"), "ate_m_lab", "paper_y");
  EXPECT_EQ(b.text, "n/a (frame printed no ate_m_lab)");
  EXPECT_EQ(render_key_lines(Table{"I", "t", "", {"c"}, {Row{"r", {b}}}, {}}), "paper_y=nan\n");
}

TEST(PaperCells, RatiosAreOfTheShownFigures) {
  const Cell paper = paper_cell("162.4 ± 19.1", 162.4, "paper Table I", "p");
  const Cell ours = run_cell(ok_run("frame_ms_mean_lab=8.120\n"), "frame_ms_mean_lab", "o");
  const Cell r = ratio_cell(paper, ours, "paper_ratio");
  EXPECT_TRUE(r.available);
  EXPECT_NEAR(r.value, 162.4 / 8.12, 1e-12);
  EXPECT_EQ(r.text, "20.0×");
  EXPECT_EQ(r.source, "paper Table I / frame_ms_mean_lab");
  EXPECT_FALSE(ratio_cell(paper, na_cell("absent"), "x").available);
  EXPECT_FALSE(ratio_cell(paper, run_cell(ok_run("z=0\n"), "z", "k"), "x").available);  // no division by 0
}

TEST(PaperCells, NumbersKeepTheirSignificantFigures) {
  EXPECT_EQ(format_number(21.37, 3), "21.4");
  EXPECT_EQ(format_number(0.0045, 3), "0.00450");
  EXPECT_EQ(format_number(162.4, 4), "162.4");
  EXPECT_EQ(format_number(-2.346, 3), "-2.35");
  EXPECT_EQ(format_number(NAN), "nan");
}

Table sample_table() {
  Table t;
  t.id = "I";
  t.title = "sample";
  t.row_header = "row";
  t.columns = {"paper", "ours"};
  t.rows.push_back(
      {"a | b",
       {paper_cell("162.4 ± 19.1", 162.4, "paper Table I", "k1"), run_cell(ok_run("x=7.5\n"), "x", "k2")}});
  t.rows.push_back({"longer row label", {dash_cell(), na_cell("dataset absent")}});
  t.notes = {"a note"};
  return t;
}

TEST(PaperTables, TextColumnsLineUpInCodePoints) {
  std::istringstream in(render_text(sample_table()));
  std::string title, header, rule, row1, row2;
  std::getline(in, title);
  std::getline(in, header);
  std::getline(in, rule);
  std::getline(in, row1);
  std::getline(in, row2);
  EXPECT_EQ(title, "Table I: sample");
  EXPECT_EQ(code_points(header), code_points(rule));
  EXPECT_EQ(code_points(row1), code_points(rule));  // "±" counts once
  EXPECT_EQ(code_points(row2), code_points(rule));
}

TEST(PaperTables, MarkdownEscapesPipesAndNamesSources) {
  const std::string md = render_markdown(sample_table());
  EXPECT_NE(md.find("| a \\| b |"), std::string::npos);
  EXPECT_NE(md.find("7.5<br><sub>`frame: x`</sub>"), std::string::npos);
  EXPECT_NE(md.find("n/a (dataset absent)"), std::string::npos);
  EXPECT_NE(md.find("- a note"), std::string::npos);
}

TEST(PaperTables, CsvQuotesAndKeyLines) {
  EXPECT_EQ(csv_field("plain"), "plain");
  EXPECT_EQ(csv_field("a,\"b\""), "\"a,\"\"b\"\"\"");
  const std::string csv = render_csv(sample_table());
  EXPECT_NE(csv.find("I,a | b,ours,7.5,7.5,frame: x,k2\n"), std::string::npos);
  EXPECT_NE(csv.find("I,longer row label,ours,n/a (dataset absent),,,\n"), std::string::npos);
  EXPECT_EQ(render_key_lines(sample_table()), "k1=162.4\nk2=7.5\n");
}

}  // namespace
}  // namespace hwr::bench::paper
