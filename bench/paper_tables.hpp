#pragma once
// `hwr-bench paper`'s tables (issue #9 item 3): the figures of the other benches' `key=value` lines
// laid out as the paper's Tables I-IV, printed for a terminal and written as Markdown and CSV.
// Every cell carries where its figure came from (a bench key of a named sub-run, the paper's table,
// or the keys a ratio was taken of), and the reason when it has none ("n/a (why)").
// Pure text handling: no processes, no files.

#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hwr::bench::paper {

// ---- key=value lines ----

// A bench's machine-readable line: `key=value`, the key made of [A-Za-z0-9_.-] starting with a letter
// or '_', the value without blanks (it may be empty). Trailing '\r' and blanks are ignored.
bool parse_key_value_line(const std::string& line, std::string* key, std::string* value);

// All key=value lines of a bench's stdout, in order. A key printed twice keeps its last value.
struct KeyValues {
  std::vector<std::pair<std::string, std::string>> lines;
  const std::string* find(const std::string& key) const;  // nullptr when absent
};
KeyValues parse_key_values(const std::string& text);

// The whole text as a number ("7.582", "-0.3", "nan", "inf"); nullopt for "3/18", "pcl-1.13", "".
std::optional<double> to_number(const std::string& text);

// ---- sub-runs ----

// One bench run as the tables see it.
struct RunResult {
  std::string id;       // "frame", "segmentation", ...: how cells name it
  std::string command;  // the exact command line (shell-quoted), to rerun it
  bool ran = false;     // false: not started (skipped, dataset absent, cannot start)
  bool ok = false;      // ran, exit code 0, not timed out
  std::string why_not;  // when !ok: "skipped (--skip frame)", "exit code 1", "timed out after 900 s"
  int exit_code = -1;
  double wall_s = 0;
  KeyValues keys;
};

// ---- cells and tables ----

struct Cell {
  std::string text;        // as shown: "7.582 ± 2.100", "158.2 ± 45.7", "n/a (frame: exit code 1)"
  std::string value_text;  // the figure as its key line prints it ("7.582"; "nan" when none)
  double value = NAN;      // the same, as a number (NaN: none)
  std::string source;      // "frame: frame_ms_mean_teddy ± frame_ms_sd_teddy", "paper Table I", ...
  std::string key;         // the paper_ key line it is printed as; empty: none
  bool available = false;  // a figure (not n/a, not a dash)
};

// The paper's figure, quoted as printed there ("162.4 ± 19.1"), with its mean as the value.
Cell paper_cell(const std::string& text, double mean, const std::string& where, const std::string& key);
// "-" (no such figure: the paper has none, or no peer exists), or the paper's "\" (not applicable).
Cell dash_cell(const std::string& text = "-");
// n/a with the reason in the text.
Cell na_cell(const std::string& why, const std::string& key = "");

// The figure of `key` in `run`, its text exactly as the bench printed it; n/a (why) when the run
// failed, was not run, or lacks the key (a key whose value is not a number is shown as printed,
// with no numeric value).
Cell run_cell(const RunResult& run, const std::string& key, const std::string& paper_key);
// "mean ± sd" from two keys of the same run (the sd part left out when its key is absent).
Cell run_mean_sd_cell(const RunResult& run, const std::string& mean_key, const std::string& sd_key,
                      const std::string& paper_key);
// numerator / denominator, shown as "21.4×" (digits significant figures); n/a when either is.
Cell ratio_cell(const Cell& numerator, const Cell& denominator, const std::string& paper_key, int digits = 3);
// A figure computed from other cells (e.g. a signed difference), with the formula as its source.
Cell derived_cell(double value, const std::string& text, const std::string& source, const std::string& key);

// "%.*g" without trailing noise: format_number(21.37, 3) == "21.4", format_number(NAN) == "nan".
std::string format_number(double v, int significant = 4);

struct Row {
  std::string label;
  std::vector<Cell> cells;  // one per Table::columns
};

struct Table {
  std::string id;     // "I", "II", ... or "R" (real datasets); key and CSV prefix "table_<id>"
  std::string title;  // one line
  std::string row_header;
  std::vector<std::string> columns;
  std::vector<Row> rows;
  std::vector<std::string> notes;  // printed under the table
};

// Fixed-width text for a terminal (widths in code points, so "±" and "×" count once), the notes under it.
std::string render_text(const Table& table);
// A GitHub Markdown table: each cell's text, then its source in small code under it; the notes as a list.
std::string render_markdown(const Table& table);
// CSV, one line per cell: table,row,column,text,value,source,key. RFC 4180 quoting.
std::string csv_header();
std::string render_csv(const Table& table);
std::string csv_field(const std::string& s);
// "paper_...=value" for every cell that has a key, in row order.
std::string render_key_lines(const Table& table);

}  // namespace hwr::bench::paper
