#pragma once
// Configuration from YAML: one file per robot or scenario. Reading is strict: a key the program
// does not know, a value of the wrong type, or a missing required key is an error whose message
// names the file, the line and the full key path, e.g.
//   "lab.yaml:14: key 'camera.fx': expected a number, got 'fast'"
//   "lab.yaml:20: unknown key 'trajectory.sped'"
// Usage:
//   auto doc = ConfigDocument::load_file("lab.yaml");          // Expected<ConfigDocument>
//   ConfigMap root = doc->root();
//   root.get("seed", &spec.seed);                              // optional: default kept if absent
//   ConfigMap cam = root.child("camera");
//   cam.require("fx", &spec.fx);
//   for (ConfigMap& p : root.list("plates")) { ... }
//   Status st = doc->finish();                                 // type errors + unknown keys
// yaml-cpp stays private to core/src.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"

namespace hwr::core {

namespace config_detail {
struct Node;
struct Document;
}  // namespace config_detail

class ConfigMap;

class ConfigDocument {
 public:
  static Expected<ConfigDocument> load_file(const std::string& path);
  // source_name is used in messages in place of a file name.
  static Expected<ConfigDocument> parse(const std::string& yaml_text, const std::string& source_name);

  // The top-level mapping. An empty document gives an empty mapping.
  ConfigMap root();
  // First recorded error (type errors, missing required keys), else the first unknown key in any
  // mapping that was read. OK when everything was consumed and well typed.
  Status finish() const;
  // All errors found by finish(), one per line.
  std::vector<std::string> all_errors() const;
  const std::string& source_name() const;

 private:
  std::shared_ptr<config_detail::Document> doc_;
};

class ConfigMap {
 public:
  // Optional keys: *out keeps its value when the key is absent. A wrong type records an error.
  ConfigMap& get(const char* key, double* out);
  ConfigMap& get(const char* key, float* out);
  ConfigMap& get(const char* key, int* out);
  ConfigMap& get(const char* key, int64_t* out);
  ConfigMap& get(const char* key, uint64_t* out);
  ConfigMap& get(const char* key, bool* out);
  ConfigMap& get(const char* key, std::string* out);
  ConfigMap& get(const char* key, std::vector<double>* out);
  ConfigMap& get(const char* key, Eigen::Vector2d* out);
  ConfigMap& get(const char* key, Eigen::Vector3d* out);
  ConfigMap& get(const char* key, Eigen::Vector4d* out);

  // Required keys: absence records an error naming the key.
  template <class T>
  ConfigMap& require(const char* key, T* out) {
    if (!has(key)) record_missing(key);
    return get(key, out);
  }

  bool has(const char* key) const;
  // A nested mapping. Absent: an empty mapping (its reads keep defaults). Not a mapping: error.
  ConfigMap child(const char* key);
  // A sequence of mappings. Absent: empty. Not a sequence of mappings: error.
  std::vector<ConfigMap> list(const char* key);
  // The keys present, in file order (for maps keyed by name).
  std::vector<std::string> keys() const;
  // "camera.intrinsics" (empty at the root).
  const std::string& path() const { return path_; }
  int line() const;

  // Records an error against this map's key (for checks beyond types, e.g. a range).
  void record_error(const char* key, const std::string& problem);

 private:
  friend class ConfigDocument;
  ConfigMap(std::shared_ptr<config_detail::Document> doc, const config_detail::Node* node, std::string path);
  const config_detail::Node* find(const char* key) const;
  void record_missing(const char* key);
  bool read_numbers(const char* key, double* out, size_t n, bool exact_count, std::vector<double>* vec);

  std::shared_ptr<config_detail::Document> doc_;
  const config_detail::Node* node_ = nullptr;  // nullptr: absent mapping
  int fallback_line_ = 0;                      // line() of an absent mapping: its nearest existing parent's
  std::string path_;
};

}  // namespace hwr::core
