// experiment: the spec reader: a SpecTree (from TOML or JSON) checked key by key into an ExperimentSpec.
#include "experiment/spec_tree.h"

#include "core/fnv1a.h"
#include "microfacet/roughness.h"
#include "microfacet/samplers.h"
#include "validate/validate.h"
#include "microgeom/assembly.h"
#include "scatter/albedo_table.h"
#include "scatter/smith_walk.h"
#include "stats/binning.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

namespace microsim::experiment {
namespace {

std::string location(const std::string& source, int line) {
  return line > 0 ? fmt::format("{}:{}", source, line) : source;
}

using Json = nlohmann::ordered_json;

using Table = SpecTable;

// The array of tables under `key` ([[material]], [[quantity]]), each with its path.
std::vector<Table> tables(const Table& top, std::string_view key) {
  if (!top.has(key)) top.fail(key, "missing (a spec needs at least one)");
  const Json& v = top.at(key);
  if (!v.is_array() || v.empty()) top.fail(key, "must be a non-empty array of tables");
  std::vector<Table> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!v[i].is_object()) top.fail(key, fmt::format("item {} must be a table", i));
    out.emplace_back(top.tree(), v[i], item_path(top.path(key), i));
  }
  return out;
}

}  // namespace

namespace {
// A key as a message prints it: itself when short and printable, else quoted as an excerpt (core/parse.h).
std::string printable_key(const std::string& key) {
  const bool plain = key.size() <= 80 && std::all_of(key.begin(), key.end(), [](char c) { return c >= 0x20 && c < 0x7f; });
  return plain ? key : quote_excerpt(key);
}
// A problem as a message prints it: at most 300 bytes (a parser's message may echo what it read).
std::string bounded(const std::string& problem) {
  return problem.size() <= 300 ? problem : problem.substr(0, 300) + fmt::format("... ({} bytes)", problem.size());
}
}  // namespace

SpecError::SpecError(std::string source, int line, std::string key, const std::string& problem)
    : std::invalid_argument(fmt::format("{}: {}: {}", location(source, line), printable_key(key), bounded(problem))),
      key_(std::move(key)),
      line_(line) {}

std::string to_string(Orders orders) { return orders == Orders::single ? "single" : "all"; }

bool SpecMaterial::isotropic() const {
  return std::all_of(alphas.begin(), alphas.end(), [](const auto& a) { return a.first == a.second; });
}

const SpecMaterial& ExperimentSpec::material(std::string_view wanted) const {
  for (const SpecMaterial& m : materials)
    if (m.name == wanted) return m;
  throw std::out_of_range(fmt::format("no material named {}", quote_excerpt(wanted)));
}

int SpecTree::line_of(std::string_view path) const {
  std::string p(path);
  while (!p.empty()) {
    if (const auto it = lines.find(p); it != lines.end()) return it->second;
    const std::size_t cut = p.find_last_of(".[");
    p = cut == std::string::npos ? "" : p.substr(0, cut);
  }
  return 0;
}

std::string child_path(std::string_view parent, std::string_view key) {
  return parent.empty() ? std::string(key) : fmt::format("{}.{}", parent, key);
}
std::string item_path(std::string_view parent, std::size_t index) { return fmt::format("{}[{}]", parent, index); }

// ---- materials -------------------------------------------------------------------------------------------

namespace {

std::pair<double, double> alpha_item(const Table& t, std::string_view key, const Json& v) {
  double ax = 0, ay = 0;
  if (v.is_array() && v.size() == 2) {
    ax = t.number_value(v[0], key);
    ay = t.number_value(v[1], key);
  } else if (v.is_number()) {
    ax = ay = t.number_value(v, key);
  } else {
    t.fail(key, "an alpha is a number or a pair [alpha_x, alpha_y]");
  }
  try {
    check_supported_alpha(t.path(key), ax, ay);
  } catch (const ParseError& e) {
    t.fail(key, e.what());
  }
  return {ax, ay};
}

std::vector<std::pair<double, double>> material_alphas(const Table& t) {
  if (t.has("alpha") == t.has("alphas")) t.fail("alphas", "give exactly one of alpha (one value or pair) and alphas (a list)");
  if (t.has("alpha")) return {alpha_item(t, "alpha", t.at("alpha"))};
  const Json& list = t.at("alphas");
  if (!list.is_array() || list.empty()) t.fail("alphas", "must be a non-empty array");
  std::vector<std::pair<double, double>> out;
  for (const Json& item : list) {
    out.push_back(alpha_item(t, "alphas", item));
    if (std::find(out.begin(), out.end() - 1, out.back()) != out.end() - 1)  // decisions are named by their alpha
      t.fail("alphas", fmt::format("alpha {},{} is given twice", out.back().first, out.back().second));
  }
  return out;
}

Material conductor_material(const Table& t) {
  if (!t.has("eta") || !t.has("k")) t.fail(t.has("eta") ? "k" : "eta", "a conductor needs eta and k");
  const std::vector<double> eta = t.numbers("eta"), k = t.numbers("k");
  if (eta.size() != k.size()) t.fail("k", fmt::format("{} values for {} of eta (one per channel)", k.size(), eta.size()));
  std::vector<std::complex<double>> ior;
  for (std::size_t c = 0; c < eta.size(); ++c) ior.emplace_back(eta[c], k[c]);
  try {
    return Material::conductor(ior);
  } catch (const std::invalid_argument& e) {
    t.fail("eta", e.what());
  }
}

Material facet_material(const Table& t) {
  const std::string type = t.string("type");
  if (type == "mirror") {
    if (t.has("eta") || t.has("k")) t.fail(t.has("eta") ? "eta" : "k", "a mirror takes no eta or k");
    return Material::mirror();
  }
  if (type == "conductor") return conductor_material(t);
  if (type != "dielectric") t.fail("type", fmt::format("{} is not a material type (mirror, conductor, dielectric)", quote_excerpt(type)));
  if (t.has("k")) t.fail("k", "a dielectric takes eta only");
  if (!t.has("eta") || !t.at("eta").is_number()) t.fail("eta", "a dielectric needs one number eta (n inside / n outside)");
  try {
    return Material::dielectric(t.number("eta"));
  } catch (const std::invalid_argument& e) {
    t.fail("eta", e.what());
  }
}

SpecMaterial read_material(const Table& t) {
  t.only_keys({"name", "ndf", "alpha", "alphas", "type", "eta", "k"}, "a material");
  SpecMaterial m;
  m.name = t.string("name");
  if (m.name.empty()) t.fail("name", "must not be empty");
  const std::string ndf = t.string("ndf", "ggx");
  const std::optional<NdfKind> kind = ndf_kind_from_string(ndf);
  if (!kind) t.fail("ndf", fmt::format("{} is not an NDF (ggx, beckmann)", quote_excerpt(ndf)));
  m.ndf = *kind;
  m.alphas = material_alphas(t);
  m.facet = facet_material(t);
  m.line = t.tree().line_of(t.path(""));
  return m;
}

}  // namespace

// ---- quantities: what every kind shares (each kind's own keys are read in its file, kind_spec) ----------------

namespace {

QuantityKind quantity_kind(const Table& t) {
  const std::string kind = t.string("kind");
  if (const std::optional<QuantityKind> k = kind_named(kind)) return *k;
  t.fail("kind", fmt::format("{} is not a quantity ({})", quote_excerpt(kind), kind_names()));
}

std::vector<double> theta_values(const Table& t) {
  if (t.has("theta") == t.has("theta_range")) t.fail("theta", "give exactly one of theta (a list) and theta_range");
  if (t.has("theta")) return t.numbers("theta");
  if (!t.at("theta_range").is_object()) t.fail("theta_range", "must be a table {from, to, count}");
  const Table r(t.tree(), t.at("theta_range"), t.path("theta_range"));
  r.only_keys({"from", "to", "count"}, "a theta_range");
  const double from = r.number("from"), to = r.number("to");
  const std::int64_t count = r.integer("count", 2, 1, 1000);
  if (count > 1 && !(to > from)) r.fail("to", fmt::format("{} must be above from ({})", to, from));
  std::vector<double> out;
  for (std::int64_t i = 0; i < count; ++i) out.push_back(count == 1 ? from : from + (to - from) * double(i) / double(count - 1));
  return out;
}

SurfaceChoice quantity_surface(const Table& t, const std::filesystem::path& spec_dir) {
  SurfaceChoice s;
  const std::string name = t.string("surface", "auto");
  if (name == "auto") return s;
  if (microgeom::find_assembly(name) != nullptr) return {SurfaceChoice::Kind::assembly, name};
  if (std::filesystem::path(name).extension() != ".exr")
    t.fail("surface", fmt::format("{} is neither auto, an assembly ({}) nor a heightmap .exr", quote_excerpt(name),
                                  microgeom::assembly_names(", ")));
  const std::filesystem::path path = spec_file_path(name, spec_dir);
  if (!std::filesystem::is_regular_file(path)) t.fail("surface", fmt::format("no heightmap file {}", path.string()));
  return {SurfaceChoice::Kind::heightmap, path.string()};
}

SpecQuantity read_quantity(const Table& t, const ExperimentSpec& spec, std::size_t index,
                           const std::filesystem::path& spec_dir) {
  SpecQuantity q;
  q.kind = quantity_kind(t);
  q.key = item_path("quantity", index);
  q.line = t.tree().line_of(q.key);
  const KindSpec& kind = kind_spec(q.kind);
  std::vector<std::string> keys{"kind", "material", "surface"};
  std::istringstream more(kind.keys);
  for (std::string key; more >> key;) keys.push_back(key);
  const bool vowel = std::string_view("aeiou").find(q.kind.name.front()) != std::string_view::npos;
  t.only_keys(keys, fmt::format("a{} {} quantity", vowel ? "n" : "", to_string(q.kind)));
  q.material = t.string("material");
  const auto m = std::find_if(spec.materials.begin(), spec.materials.end(), [&](const auto& x) { return x.name == q.material; });
  if (m == spec.materials.end()) t.fail("material", fmt::format("no material named {}", quote_excerpt(q.material)));
  q.surface = quantity_surface(t, spec_dir);
  kind.read(t, q, *m, spec_dir);
  return q;
}

}  // namespace

double read_target(const SpecTable& t, const std::string& key, double below, const std::string& what) {
  const double target = t.number(key);
  if (!(target > 0)) t.fail(key, fmt::format("{} must be > 0", target));
  if (target >= below) t.fail(key, fmt::format("{}: {}", target, what));
  return target;
}

std::vector<Direction> read_directions(const SpecTable& t, bool from_inside_ok) {
  const std::string theta_key = t.has("theta") ? "theta" : "theta_range";
  std::vector<Direction> out;
  for (double theta : theta_values(t)) {
    const bool above = theta >= 0 && theta < 90, inside = from_inside_ok && theta > 90 && theta <= 180;
    if (!above && !inside)
      t.fail(theta_key, fmt::format("theta {} deg is {} (this quantity takes [0, 90){})", theta,
                                    theta >= 90 && theta <= 180 ? "at or below the horizon" : "not an angle of a view",
                                    from_inside_ok ? ", or (90, 180] from inside a dielectric" : ""));
    for (double phi : t.has("phi") ? t.numbers("phi") : std::vector<double>{0.0}) {
      const auto same = [&](const Direction& d) { return d.theta_deg == theta && d.phi_deg == phi; };
      if (std::any_of(out.begin(), out.end(), same))  // decisions are named by their view
        t.fail(theta_key, fmt::format("the view theta {} phi {} is given twice", theta, phi));
      out.push_back({theta, phi});
    }
  }
  return out;
}

std::filesystem::path spec_file_path(const std::string& name, const std::filesystem::path& spec_dir) {
  return std::filesystem::path(name).is_absolute() ? std::filesystem::path(name) : spec_dir / name;
}

Orders read_orders(const SpecTable& t) {
  const std::string orders = t.string("orders", "single");
  if (orders != "single" && orders != "all") t.fail("orders", fmt::format("{}: single or all", quote_excerpt(orders)));
  return orders == "single" ? Orders::single : Orders::all;
}

void read_walk_kernel(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m) {
  const std::string kernel = t.string("walk_kernel", "scalar");
  if (kernel != "scalar" && kernel != "lanes") t.fail("walk_kernel", fmt::format("{}: scalar or lanes", quote_excerpt(kernel)));
  if (kernel == "scalar") return;
  if (!smith_walk_lanes_support(m.ndf, HeightDistribution::uniform, m.facet))
    t.fail("walk_kernel", fmt::format("lanes walks GGX mirrors, conductors and dielectrics (material {} is {} {}); "
                                      "scalar walks every case", quote_excerpt(m.name), to_string(m.ndf), m.facet.describe()));
  q.settings["walk_kernel"] = kernel;
}

void read_validator_rows(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m) {
  q.rows = int(t.integer("rows", 31, 3, kMaxBinningRows));
  if (q.rows % 2 == 0) t.fail("rows", fmt::format("{} must be odd", q.rows));
  if (m.ndf != NdfKind::ggx)
    t.fail("material", fmt::format("material {}: {} is for GGX (the ellipsoid oracle, the zoo)", quote_excerpt(m.name),
                                   to_string(q.kind)));
}

bool dump_has_bsdf(const SpecQuantity& q) {
  return q.dump_pdf == "bsdf" || SampleColumns::parse(q.dump_columns).channels() > 0;
}

ExperimentSpec read_spec(const SpecTree& tree) {
  const Table top(tree, tree.root, "");
  top.only_keys({"name", "seed", "material", "quantity"}, "a spec");
  ExperimentSpec spec;
  spec.source = tree.source;
  spec.name = top.string("name", std::filesystem::path(tree.source).stem().string());
  if (top.has("seed") && !(top.at("seed").is_number_unsigned() || top.at("seed").is_number_integer()))
    top.fail("seed", "must be a non-negative integer");
  if (top.has("seed") && top.at("seed").is_number_integer() && !top.at("seed").is_number_unsigned() && top.at("seed").get<std::int64_t>() < 0)
    top.fail("seed", "must be a non-negative integer");
  spec.seed = top.has("seed") ? top.at("seed").get<std::uint64_t>() : 1;
  for (const Table& t : tables(top, "material")) {
    spec.materials.push_back(read_material(t));
    for (std::size_t i = 0; i + 1 < spec.materials.size(); ++i)
      if (spec.materials[i].name == spec.materials.back().name)
        t.fail("name", fmt::format("material {} is defined twice", quote_excerpt(spec.materials.back().name)));
  }
  const std::filesystem::path dir = std::filesystem::path(tree.source).parent_path();
  std::size_t index = 0;
  for (const Table& t : tables(top, "quantity")) spec.quantities.push_back(read_quantity(t, spec, index++, dir));
  return spec;
}

ExperimentSpec parse_spec_toml(std::string_view text, const std::string& source) {
  return read_spec(toml_tree(text, source));
}

ExperimentSpec parse_spec_json(std::string_view text, const std::string& source) {
  return read_spec(json_tree(text, source));
}

ExperimentSpec load_spec(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in || std::filesystem::is_directory(path)) throw SpecError(path.string(), 0, "(file)", "cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  if (path.extension() == ".json") return parse_spec_json(text.str(), path.string());
  return parse_spec_toml(text.str(), path.string());
}

std::vector<PathOption> spec_input_files(const ExperimentSpec& spec) {
  std::vector<PathOption> files{{"SPEC", spec.source}};
  for (const SpecQuantity& q : spec.quantities) {
    if (!q.dump.empty()) files.push_back({q.key + ".dump", q.dump});
    if (q.surface.kind == SurfaceChoice::Kind::heightmap) files.push_back({q.key + ".surface", q.surface.name});
    for (const char* key : {"plugin", "dump", "eval", "cells"})
      if (const auto it = q.settings.find(key); it != q.settings.end() && it->is_string() && !it->get<std::string>().empty())
        files.push_back({q.key + "." + key, it->get<std::string>()});
  }
  return files;
}

}  // namespace microsim::experiment
