#include "hwr/core/config.hpp"

#include "hwr/core/file_io.hpp"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace hwr::core {
namespace config_detail {

struct Node {
  enum class Kind { kNull, kScalar, kSequence, kMap };
  Kind kind = Kind::kNull;
  int line = 0;  // 1-based
  std::string scalar;
  std::vector<Node> items;                            // kSequence
  std::vector<std::pair<std::string, Node>> entries;  // kMap, file order
  std::vector<int> key_lines;      // kMap: line of each key (a nested value starts below it)
  mutable std::vector<bool> used;  // kMap: entry read
  mutable bool entered = false;    // kMap: a ConfigMap was made for it
};

struct Document {
  std::string source;
  Node root;
  std::vector<std::string> errors;  // in order found
};

namespace {

Status convert(const YAML::Node& in, Node* out, const std::string& source) {
  out->line = in.Mark().line + 1;
  switch (in.Type()) {
    case YAML::NodeType::Undefined:
    case YAML::NodeType::Null:
      out->kind = Node::Kind::kNull;
      return Status::Ok();
    case YAML::NodeType::Scalar:
      out->kind = Node::Kind::kScalar;
      out->scalar = in.Scalar();
      return Status::Ok();
    case YAML::NodeType::Sequence:
      out->kind = Node::Kind::kSequence;
      out->items.resize(in.size());
      for (size_t i = 0; i < in.size(); ++i) HWR_RETURN_IF_ERROR(convert(in[i], &out->items[i], source));
      return Status::Ok();
    case YAML::NodeType::Map:
      out->kind = Node::Kind::kMap;
      for (const auto& kv : in) {
        if (!kv.first.IsScalar()) {
          return ParseError(source + ":" + std::to_string(kv.first.Mark().line + 1) +
                            ": mapping keys must be plain words");
        }
        const std::string key = kv.first.Scalar();
        for (const auto& e : out->entries) {
          if (e.first == key) {
            return ParseError(source + ":" + std::to_string(kv.first.Mark().line + 1) + ": duplicate key '" +
                              key + "'");
          }
        }
        out->entries.emplace_back(key, Node{});
        out->key_lines.push_back(kv.first.Mark().line + 1);
        HWR_RETURN_IF_ERROR(convert(kv.second, &out->entries.back().second, source));
      }
      out->used.assign(out->entries.size(), false);
      return Status::Ok();
  }
  return Internal("unknown YAML node type");
}

void collect_unknown(const Node& n, const std::string& path, const std::string& source,
                     std::vector<std::string>* out) {
  if (n.kind == Node::Kind::kMap) {
    if (!n.entered) return;  // never read: its parent key was reported if unused
    for (size_t i = 0; i < n.entries.size(); ++i) {
      const std::string full = path.empty() ? n.entries[i].first : path + "." + n.entries[i].first;
      if (!n.used[i]) {
        out->push_back(source + ":" + std::to_string(n.key_lines[i]) + ": unknown key '" + full + "'");
      } else {
        collect_unknown(n.entries[i].second, full, source, out);
      }
    }
  } else if (n.kind == Node::Kind::kSequence) {
    for (size_t i = 0; i < n.items.size(); ++i) {
      collect_unknown(n.items[i], path + "[" + std::to_string(i) + "]", source, out);
    }
  }
}

bool parse_double(const std::string& s, double* out) {
  if (s.empty()) return false;
  const char* b = s.c_str();
  char* e = nullptr;
  errno = 0;
  const double v = std::strtod(b, &e);
  // ERANGE on underflow still yields the nearest (subnormal or zero) value; only overflow is an error.
  if (e == b || *e != '\0' || (errno == ERANGE && std::fabs(v) == HUGE_VAL)) {
    // YAML spellings of special values.
    if (s == ".nan" || s == ".NaN" || s == ".NAN") {
      *out = std::nan("");
      return true;
    }
    if (s == ".inf" || s == ".Inf" || s == "+.inf") {
      *out = HUGE_VAL;
      return true;
    }
    if (s == "-.inf" || s == "-.Inf") {
      *out = -HUGE_VAL;
      return true;
    }
    return false;
  }
  *out = v;
  return true;
}

bool parse_int64(const std::string& s, int64_t* out) {
  if (s.empty()) return false;
  // YAML 1.2 core schema: decimal (a leading zero is still decimal), 0x hex, 0o octal. strtoll's
  // base 0 would read "010" as octal 8 and reject "0o17".
  const bool negative = s[0] == '-';
  size_t i = (s[0] == '-' || s[0] == '+') ? 1 : 0;
  int base = 10;
  if (s.compare(i, 2, "0x") == 0 || s.compare(i, 2, "0X") == 0) {
    base = 16;
    i += 2;
  } else if (s.compare(i, 2, "0o") == 0) {
    base = 8;
    i += 2;
  }
  // A digit must follow (strtoll would also skip spaces or take a second sign).
  if (i < s.size() && std::isxdigit(static_cast<unsigned char>(s[i]))) {
    const std::string digits = (negative ? "-" : "") + s.substr(i);
    char* e = nullptr;
    errno = 0;
    const long long v = std::strtoll(digits.c_str(), &e, base);
    if (*e == '\0' && errno != ERANGE) {
      *out = v;
      return true;
    }
  }
  // Accept integral floats written like 1e6 or 30.0.
  double d = 0;
  if (base == 10 && parse_double(s, &d) && std::isfinite(d) && d == std::floor(d) && std::fabs(d) < 9.2e18) {
    *out = static_cast<int64_t>(d);
    return true;
  }
  return false;
}

bool parse_bool(const std::string& s, bool* out) {
  if (s == "true" || s == "True" || s == "TRUE" || s == "yes" || s == "on") {
    *out = true;
    return true;
  }
  if (s == "false" || s == "False" || s == "FALSE" || s == "no" || s == "off") {
    *out = false;
    return true;
  }
  return false;
}

}  // namespace
}  // namespace config_detail

using config_detail::Document;
using config_detail::Node;

Expected<ConfigDocument> ConfigDocument::parse(const std::string& yaml_text, const std::string& source_name) {
  auto doc = std::make_shared<Document>();
  doc->source = source_name;
  YAML::Node y;
  try {
    y = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    return ParseError(source_name + ":" + std::to_string(e.mark.line + 1) + ": YAML syntax error: " + e.msg);
  }
  Status st = config_detail::convert(y, &doc->root, source_name);
  if (!st.ok()) return st;
  if (doc->root.kind == Node::Kind::kNull) {
    doc->root.kind = Node::Kind::kMap;  // empty file: empty mapping
  } else if (doc->root.kind != Node::Kind::kMap) {
    return ParseError(source_name + ":" + std::to_string(doc->root.line) +
                      ": the top level must be a mapping of keys");
  }
  ConfigDocument out;
  out.doc_ = std::move(doc);
  return out;
}

Expected<ConfigDocument> ConfigDocument::load_file(const std::string& path) {
  std::string text;
  HWR_RETURN_IF_ERROR(read_file(path, &text));
  return parse(text, path);
}

ConfigMap ConfigDocument::root() { return ConfigMap(doc_, &doc_->root, ""); }

std::vector<std::string> ConfigDocument::all_errors() const {
  std::vector<std::string> out = doc_->errors;
  config_detail::collect_unknown(doc_->root, "", doc_->source, &out);
  return out;
}

Status ConfigDocument::finish() const {
  const std::vector<std::string> errs = all_errors();
  if (errs.empty()) return Status::Ok();
  return InvalidArgument(errs.front());
}

const std::string& ConfigDocument::source_name() const { return doc_->source; }

ConfigMap::ConfigMap(std::shared_ptr<Document> doc, const Node* node, std::string path)
    : doc_(std::move(doc)), node_(node), path_(std::move(path)) {
  if (node_ != nullptr) node_->entered = true;
}

int ConfigMap::line() const { return node_ ? node_->line : fallback_line_; }

const Node* ConfigMap::find(const char* key) const {
  if (node_ == nullptr) return nullptr;
  for (size_t i = 0; i < node_->entries.size(); ++i) {
    if (node_->entries[i].first == key) {
      node_->used[i] = true;
      return &node_->entries[i].second;
    }
  }
  return nullptr;
}

bool ConfigMap::has(const char* key) const {
  if (node_ == nullptr) return false;
  for (const auto& e : node_->entries) {
    if (e.first == key) return true;
  }
  return false;
}

std::vector<std::string> ConfigMap::keys() const {
  std::vector<std::string> out;
  if (node_ == nullptr) return out;
  for (const auto& e : node_->entries) out.push_back(e.first);
  return out;
}

void ConfigMap::record_error(const char* key, const std::string& problem) {
  // The key's own line; for a key that is absent, the line of this mapping (or, when the mapping
  // itself is absent, of the nearest enclosing one that exists).
  int line = this->line();
  if (node_ != nullptr) {
    for (size_t i = 0; i < node_->entries.size(); ++i) {
      if (node_->entries[i].first == key) line = node_->key_lines[i];
    }
  }
  const std::string full = path_.empty() ? std::string(key) : path_ + "." + key;
  doc_->errors.push_back(doc_->source + ":" + std::to_string(line) + ": key '" + full + "': " + problem);
}

void ConfigMap::record_missing(const char* key) { record_error(key, "required but missing"); }

namespace {
std::string describe(const Node& n) {
  switch (n.kind) {
    case Node::Kind::kNull:
      return "nothing";
    case Node::Kind::kScalar:
      return "'" + n.scalar + "'";
    case Node::Kind::kSequence:
      return "a list";
    case Node::Kind::kMap:
      return "a mapping";
  }
  return "?";
}
}  // namespace

ConfigMap& ConfigMap::get(const char* key, double* out) {
  const Node* n = find(key);
  if (n == nullptr) return *this;
  double v = 0;
  if (n->kind != Node::Kind::kScalar || !config_detail::parse_double(n->scalar, &v)) {
    record_error(key, "expected a number, got " + describe(*n));
  } else {
    *out = v;
  }
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, float* out) {
  double v = *out;
  const bool present = has(key);
  get(key, &v);
  if (present) *out = static_cast<float>(v);
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, int64_t* out) {
  const Node* n = find(key);
  if (n == nullptr) return *this;
  int64_t v = 0;
  if (n->kind != Node::Kind::kScalar || !config_detail::parse_int64(n->scalar, &v)) {
    record_error(key, "expected an integer, got " + describe(*n));
  } else {
    *out = v;
  }
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, int* out) {
  int64_t v = *out;
  const size_t before = doc_->errors.size();
  const bool present = has(key);
  get(key, &v);
  if (!present || doc_->errors.size() != before) return *this;
  if (v < INT32_MIN || v > INT32_MAX) {
    record_error(key, "integer " + std::to_string(v) + " out of range");
  } else {
    *out = static_cast<int>(v);
  }
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, uint64_t* out) {
  int64_t v = static_cast<int64_t>(*out);
  const size_t before = doc_->errors.size();
  const bool present = has(key);
  get(key, &v);
  if (!present || doc_->errors.size() != before) return *this;
  if (v < 0) {
    record_error(key, "expected a non-negative integer, got " + std::to_string(v));
  } else {
    *out = static_cast<uint64_t>(v);
  }
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, bool* out) {
  const Node* n = find(key);
  if (n == nullptr) return *this;
  bool v = false;
  if (n->kind != Node::Kind::kScalar || !config_detail::parse_bool(n->scalar, &v)) {
    record_error(key, "expected true or false, got " + describe(*n));
  } else {
    *out = v;
  }
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, std::string* out) {
  const Node* n = find(key);
  if (n == nullptr) return *this;
  if (n->kind != Node::Kind::kScalar) {
    record_error(key, "expected a text value, got " + describe(*n));
  } else {
    *out = n->scalar;
  }
  return *this;
}

bool ConfigMap::read_numbers(const char* key, double* out, size_t n_expected, bool exact_count,
                             std::vector<double>* vec) {
  const Node* n = find(key);
  if (n == nullptr) return false;
  if (n->kind != Node::Kind::kSequence) {
    record_error(key, "expected a list of numbers, got " + describe(*n));
    return false;
  }
  if (exact_count && n->items.size() != n_expected) {
    record_error(
        key, "expected " + std::to_string(n_expected) + " numbers, got " + std::to_string(n->items.size()));
    return false;
  }
  std::vector<double> tmp(n->items.size());
  for (size_t i = 0; i < n->items.size(); ++i) {
    const Node& it = n->items[i];
    if (it.kind != Node::Kind::kScalar || !config_detail::parse_double(it.scalar, &tmp[i])) {
      record_error(key, "element " + std::to_string(i) + ": expected a number, got " + describe(it));
      return false;
    }
  }
  if (vec != nullptr) *vec = std::move(tmp);
  if (out != nullptr) {
    for (size_t i = 0; i < n_expected; ++i) out[i] = tmp[i];
  }
  return true;
}

ConfigMap& ConfigMap::get(const char* key, std::vector<double>* out) {
  read_numbers(key, nullptr, 0, false, out);
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, Eigen::Vector2d* out) {
  double v[2];
  if (read_numbers(key, v, 2, true, nullptr)) *out = Eigen::Vector2d(v[0], v[1]);
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, Eigen::Vector3d* out) {
  double v[3];
  if (read_numbers(key, v, 3, true, nullptr)) *out = Eigen::Vector3d(v[0], v[1], v[2]);
  return *this;
}

ConfigMap& ConfigMap::get(const char* key, Eigen::Vector4d* out) {
  double v[4];
  if (read_numbers(key, v, 4, true, nullptr)) *out = Eigen::Vector4d(v[0], v[1], v[2], v[3]);
  return *this;
}

ConfigMap ConfigMap::child(const char* key) {
  const Node* n = find(key);
  const std::string full = path_.empty() ? std::string(key) : path_ + "." + key;
  if (n != nullptr && n->kind != Node::Kind::kNull && n->kind != Node::Kind::kMap) {
    record_error(key, "expected a mapping of keys, got " + describe(*n));
    n = nullptr;
  }
  if (n == nullptr || n->kind == Node::Kind::kNull) {
    // Absent: errors against its keys point at the nearest mapping that exists.
    ConfigMap absent(doc_, nullptr, full);
    absent.fallback_line_ = line();
    return absent;
  }
  return ConfigMap(doc_, n, full);
}

std::vector<ConfigMap> ConfigMap::list(const char* key) {
  std::vector<ConfigMap> out;
  const Node* n = find(key);
  if (n == nullptr || n->kind == Node::Kind::kNull) return out;
  const std::string full = path_.empty() ? std::string(key) : path_ + "." + key;
  if (n->kind != Node::Kind::kSequence) {
    record_error(key, "expected a list, got " + describe(*n));
    return out;
  }
  for (size_t i = 0; i < n->items.size(); ++i) {
    const Node& it = n->items[i];
    if (it.kind != Node::Kind::kMap) {
      record_error(key, "element " + std::to_string(i) + ": expected a mapping of keys, got " + describe(it));
      continue;
    }
    out.push_back(ConfigMap(doc_, &it, full + "[" + std::to_string(i) + "]"));
  }
  return out;
}

}  // namespace hwr::core
