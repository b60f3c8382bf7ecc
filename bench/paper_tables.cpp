#include "paper_tables.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace hwr::bench::paper {
namespace {

bool key_char(char c, bool first) {
  const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
  return first ? alpha : alpha || (c >= '0' && c <= '9') || c == '.' || c == '-';
}

bool blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

// Display width of UTF-8 text: code points, not bytes (the tables hold "±", "×", "—").
size_t width(const std::string& s) {
  size_t n = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++n;
  return n;
}

std::string pad(const std::string& s, size_t w, bool right) {
  const size_t n = width(s);
  if (n >= w) return s;
  return right ? std::string(w - n, ' ') + s : s + std::string(w - n, ' ');
}

std::string markdown_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

Cell missing(const RunResult& run, const std::string& key, const std::string& paper_key) {
  if (!run.ok) return na_cell(run.id + ": " + run.why_not, paper_key);
  return na_cell(run.id + " printed no " + key, paper_key);
}

}  // namespace

bool parse_key_value_line(const std::string& line, std::string* key, std::string* value) {
  size_t end = line.size();
  while (end > 0 && blank(line[end - 1])) --end;
  const size_t eq = line.find('=');
  if (eq == std::string::npos || eq == 0 || eq >= end) return false;
  for (size_t i = 0; i < eq; ++i)
    if (!key_char(line[i], i == 0)) return false;
  for (size_t i = eq + 1; i < end; ++i)
    if (blank(line[i])) return false;
  *key = line.substr(0, eq);
  *value = line.substr(eq + 1, end - eq - 1);
  return true;
}

const std::string* KeyValues::find(const std::string& key) const {
  for (auto it = lines.rbegin(); it != lines.rend(); ++it)
    if (it->first == key) return &it->second;
  return nullptr;
}

KeyValues parse_key_values(const std::string& text) {
  KeyValues kv;
  std::istringstream in(text);
  std::string key, value;
  for (std::string line; std::getline(in, line);)
    if (parse_key_value_line(line, &key, &value)) kv.lines.emplace_back(key, value);
  return kv;
}

std::optional<double> to_number(const std::string& text) {
  if (text.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return std::nullopt;
  return v;
}

std::string format_number(double v, int significant) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  // Fixed notation for the magnitudes of these tables, with `significant` figures.
  const double a = std::abs(v);
  if (a != 0 && (a >= 1e7 || a < 1e-4)) {
    std::snprintf(buf, sizeof(buf), "%.*g", significant, v);
    return buf;
  }
  const int int_digits = a >= 1 ? static_cast<int>(std::floor(std::log10(a))) + 1 : 0;
  int decimals = std::max(0, significant - int_digits);
  if (a > 0 && a < 1) decimals = significant - 1 - static_cast<int>(std::floor(std::log10(a)));
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

Cell paper_cell(const std::string& text, double mean, const std::string& where, const std::string& key) {
  Cell c;
  c.text = text;
  c.value = mean;
  // The key line quotes the paper's mean as printed ("162.4" of "162.4 ± 19.1").
  const std::string first = text.substr(0, text.find(' '));
  c.value_text = to_number(first) ? first : format_number(mean, 6);
  c.source = where;
  c.key = key;
  c.available = true;
  return c;
}

Cell dash_cell(const std::string& text) {
  Cell c;
  c.text = text;
  c.value_text = "nan";
  return c;
}

Cell na_cell(const std::string& why, const std::string& key) {
  Cell c;
  c.text = "n/a (" + why + ")";
  c.value_text = "nan";
  c.key = key;
  return c;
}

Cell run_cell(const RunResult& run, const std::string& key, const std::string& paper_key) {
  const std::string* v = run.ok ? run.keys.find(key) : nullptr;
  if (v == nullptr) return missing(run, key, paper_key);
  Cell c;
  c.text = *v;
  c.value_text = *v;
  c.source = run.id + ": " + key;
  c.key = paper_key;
  const auto n = to_number(*v);
  c.value = n ? *n : NAN;
  c.available = true;
  return c;
}

Cell run_mean_sd_cell(const RunResult& run, const std::string& mean_key, const std::string& sd_key,
                      const std::string& paper_key) {
  Cell c = run_cell(run, mean_key, paper_key);
  if (!c.available) return c;
  if (const std::string* sd = run.keys.find(sd_key)) {
    c.text += " ± " + *sd;
    c.source += " ± " + sd_key;
  }
  return c;
}

Cell ratio_cell(const Cell& numerator, const Cell& denominator, const std::string& paper_key, int digits) {
  if (!numerator.available || !denominator.available || std::isnan(numerator.value) ||
      std::isnan(denominator.value) || denominator.value == 0)
    return na_cell("no " + std::string(!numerator.available || std::isnan(numerator.value) ? "numerator"
                                                                                           : "denominator"),
                   paper_key);
  const double r = numerator.value / denominator.value;
  Cell c;
  c.value = r;
  c.value_text = format_number(r, digits + 1);
  c.text = format_number(r, digits) + "×";
  const auto name = [](const Cell& x) {
    const size_t colon = x.source.find(": ");
    std::string s = colon == std::string::npos ? x.source : x.source.substr(colon + 2);
    const size_t pm = s.find(" ± ");
    return pm == std::string::npos ? s : s.substr(0, pm);
  };
  c.source = name(numerator) + " / " + name(denominator);
  c.key = paper_key;
  c.available = true;
  return c;
}

Cell derived_cell(double value, const std::string& text, const std::string& source, const std::string& key) {
  Cell c;
  c.value = value;
  // The key line prints the figure as the table shows it, where the text is the number alone.
  c.value_text = to_number(text) ? text : format_number(value, 5);
  c.text = text;
  c.source = source;
  c.key = key;
  c.available = !std::isnan(value);
  return c;
}

std::string render_text(const Table& table) {
  std::vector<size_t> w(table.columns.size() + 1, 0);
  w[0] = width(table.row_header);
  for (size_t k = 0; k < table.columns.size(); ++k) w[k + 1] = width(table.columns[k]);
  for (const Row& r : table.rows) {
    w[0] = std::max(w[0], width(r.label));
    for (size_t k = 0; k < r.cells.size() && k < table.columns.size(); ++k)
      w[k + 1] = std::max(w[k + 1], width(r.cells[k].text));
  }
  std::string out = "Table " + table.id + ": " + table.title + "\n";
  std::string line = pad(table.row_header, w[0], false);
  for (size_t k = 0; k < table.columns.size(); ++k) line += " | " + pad(table.columns[k], w[k + 1], true);
  out += line + "\n";
  size_t total = w[0];
  for (size_t k = 1; k < w.size(); ++k) total += 3 + w[k];
  out += std::string(total, '-') + "\n";
  for (const Row& r : table.rows) {
    line = pad(r.label, w[0], false);
    for (size_t k = 0; k < table.columns.size(); ++k)
      line += " | " + pad(k < r.cells.size() ? r.cells[k].text : "", w[k + 1], true);
    out += line + "\n";
  }
  for (const std::string& n : table.notes) out += "  " + n + "\n";
  return out;
}

std::string render_markdown(const Table& table) {
  std::string out = "### Table " + table.id + ": " + markdown_escape(table.title) + "\n\n";
  out += "| " + markdown_escape(table.row_header) + " |";
  for (const std::string& c : table.columns) out += " " + markdown_escape(c) + " |";
  out += "\n|---|";
  for (size_t k = 0; k < table.columns.size(); ++k) out += "---:|";
  out += "\n";
  for (const Row& r : table.rows) {
    out += "| " + markdown_escape(r.label) + " |";
    for (size_t k = 0; k < table.columns.size(); ++k) {
      if (k >= r.cells.size()) {
        out += " |";
        continue;
      }
      const Cell& c = r.cells[k];
      out += " " + markdown_escape(c.text);
      if (!c.source.empty()) out += "<br><sub>`" + markdown_escape(c.source) + "`</sub>";
      out += " |";
    }
    out += "\n";
  }
  if (!table.notes.empty()) {
    out += "\n";
    for (const std::string& n : table.notes) out += "- " + markdown_escape(n) + "\n";
  }
  return out + "\n";
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string csv_header() { return "table,row,column,text,value,source,key\n"; }

std::string render_csv(const Table& table) {
  std::string out;
  for (const Row& r : table.rows) {
    for (size_t k = 0; k < r.cells.size() && k < table.columns.size(); ++k) {
      const Cell& c = r.cells[k];
      out += csv_field(table.id) + "," + csv_field(r.label) + "," + csv_field(table.columns[k]) + "," +
             csv_field(c.text) + "," + csv_field(c.available ? c.value_text : "") + "," +
             csv_field(c.source) + "," + csv_field(c.key) + "\n";
    }
  }
  return out;
}

std::string render_key_lines(const Table& table) {
  std::string out;
  for (const Row& r : table.rows)
    for (const Cell& c : r.cells)
      if (!c.key.empty()) out += c.key + "=" + (c.value_text.empty() ? "nan" : c.value_text) + "\n";
  return out;
}

}  // namespace hwr::bench::paper
