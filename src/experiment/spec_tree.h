// experiment: the document a spec file holds, whatever its syntax: a JSON tree (keys in the file's order)
// and the line of every key path ("quantity[1].target_tv"), from toml++'s source regions or located in
// JSON text. spec.cpp reads an ExperimentSpec from it; spec_toml.cpp and spec_json.cpp build it.
#pragma once

#include "core/parse.h"
#include "experiment/spec.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <map>
#include <string>
#include <string_view>

namespace microsim::experiment {

struct SpecTree {
  nlohmann::ordered_json root = nlohmann::ordered_json::object();
  std::map<std::string, int> lines;  // key path -> line (1-based)
  std::string source;

  // The line of `path`, or of its closest enclosing path that has one; 0 if none.
  int line_of(std::string_view path) const;
};

// "parent.key" / "key" when parent is "", and "parent[index]".
std::string child_path(std::string_view parent, std::string_view key);
std::string item_path(std::string_view parent, std::size_t index);

using SpecJson = nlohmann::ordered_json;

// One table (object) of the spec and its key path: typed getters that throw SpecError naming key and line.
class SpecTable {
public:
  SpecTable(const SpecTree& tree, const SpecJson& value, std::string path) : tree_(tree), value_(value), path_(std::move(path)) {}

  [[noreturn]] void fail(std::string_view key, const std::string& problem) const {
    const std::string p = key.empty() ? path_ : child_path(path_, key);
    throw SpecError(tree_.source, tree_.line_of(p), p, problem);
  }
  bool has(std::string_view key) const { return value_.contains(std::string(key)); }
  const SpecJson& at(std::string_view key) const { return value_.at(std::string(key)); }
  std::string path(std::string_view key) const { return child_path(path_, key); }
  const SpecTree& tree() const { return tree_; }

  // Refuses any key not in `allowed`, naming it and the keys that are allowed.
  void only_keys(const std::vector<std::string>& allowed, std::string_view what) const {
    for (const auto& [key, v] : value_.items())
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
        fail(key, fmt::format("unknown key of {} (its keys: {})", what, fmt::join(allowed, ", ")));
  }
  std::string string(std::string_view key, std::optional<std::string> fallback = std::nullopt) const {
    if (!has(key)) {
      if (fallback) return *fallback;
      fail(key, "missing (required)");
    }
    if (!at(key).is_string()) fail(key, "must be a string");
    return at(key).get<std::string>();
  }
  double number(std::string_view key, std::optional<double> fallback = std::nullopt) const {
    if (!has(key)) {
      if (fallback) return *fallback;
      fail(key, "missing (required)");
    }
    return number_value(at(key), key);
  }
  double number_value(const SpecJson& v, std::string_view key) const {
    if (!v.is_number()) fail(key, "must be a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, "must be finite");
    return x;
  }
  std::int64_t integer(std::string_view key, std::int64_t fallback, std::int64_t lo, std::int64_t hi) const {
    if (!has(key)) return fallback;
    if (!at(key).is_number_integer()) fail(key, "must be an integer");
    const std::int64_t x = at(key).get<std::int64_t>();
    if (x < lo || x > hi) fail(key, fmt::format("{} is outside [{}, {}]", x, lo, hi));
    return x;
  }
  bool boolean(std::string_view key, bool fallback) const {
    if (!has(key)) return fallback;
    if (!at(key).is_boolean()) fail(key, "must be true or false");
    return at(key).get<bool>();
  }
  // A number or an array of numbers, as a list.
  std::vector<double> numbers(std::string_view key) const {
    const SpecJson& v = at(key);
    if (!v.is_array()) return {number_value(v, key)};
    if (v.empty()) fail(key, "must not be empty");
    std::vector<double> out;
    for (const SpecJson& item : v) out.push_back(number_value(item, key));
    return out;
  }

private:
  const SpecTree& tree_;
  const SpecJson& value_;
  std::string path_;
};


// ---- what the kinds' readers share (spec.cpp) -----------------------------------------------------------------

// A quantity's target under `key`: > 0 and below `below` (`what`: the bound's reason), else a SpecError.
double read_target(const SpecTable& t, const std::string& key, double below, const std::string& what);
// The views: theta (a list) or theta_range, times phi (default [0]); theta in [0, 90), or also (90, 180] (light
// from inside a dielectric) where `from_inside_ok`.
std::vector<Direction> read_directions(const SpecTable& t, bool from_inside_ok);
Orders read_orders(const SpecTable& t);  // orders: single (default) or all
// The Smith walk's kernel of a quantity that may be walked (albedo, scattering): `walk_kernel` "scalar" (default)
// or "lanes" (the SIMD walk of scatter/smith_walk.h: GGX facets other than Lambertian; the same walk, other random
// numbers), kept in its settings only when lanes, so that a spec without the key keeps its digest.
void read_walk_kernel(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m);
// The validator's rows (odd, default 31) of a quantity measured against GGX's D_v (vndf, validation).
void read_validator_rows(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m);
// A file named in a spec: as given when absolute, else in the spec's folder.
std::filesystem::path spec_file_path(const std::string& name, const std::filesystem::path& spec_dir);

// A kind's reader (the registry's, measurement_registry.cpp): its target and options, after its keys were
// checked (KindSpec::keys) and the material and surface read.
using ReadKindSpec = void (*)(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m,
                              const std::filesystem::path& spec_dir);
struct KindSpec {
  const char* keys;  // its keys besides kind, material and surface, space-separated
  ReadKindSpec read;
  // Its members of the spec's canonical description (canonical_spec) beyond every quantity's; null: none.
  nlohmann::json (*canonical)(const SpecQuantity& q) = nullptr;
};
const KindSpec& kind_spec(QuantityKind kind);                   // measurement_registry.cpp
std::optional<QuantityKind> kind_named(std::string_view name);  // measurement_registry.cpp
std::string kind_names();                                        // "albedo, vndf, ..."

SpecTree toml_tree(std::string_view text, const std::string& source);  // throws SpecError
SpecTree json_tree(std::string_view text, const std::string& source);  // throws SpecError
ExperimentSpec read_spec(const SpecTree& tree);                         // throws SpecError

}  // namespace microsim::experiment
