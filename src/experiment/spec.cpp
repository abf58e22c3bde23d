// experiment: the spec reader: a SpecTree (from TOML or JSON) checked key by key into an ExperimentSpec.
#include "experiment/spec_tree.h"

#include "core/fnv1a.h"
#include "microfacet/roughness.h"
#include "microfacet/samplers.h"
#include "validate/validate.h"
#include "microgeom/assembly.h"
#include "scatter/albedo_table.h"
#include "stats/binning.h"

#include <fmt/core.h>
#include <fmt/format.h>

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

// One table (object) of the spec and its key path: typed getters that throw SpecError naming key and line.
class Table {
public:
  Table(const SpecTree& tree, const Json& value, std::string path) : tree_(tree), value_(value), path_(std::move(path)) {}

  [[noreturn]] void fail(std::string_view key, const std::string& problem) const {
    const std::string p = key.empty() ? path_ : child_path(path_, key);
    throw SpecError(tree_.source, tree_.line_of(p), p, problem);
  }
  bool has(std::string_view key) const { return value_.contains(std::string(key)); }
  const Json& at(std::string_view key) const { return value_.at(std::string(key)); }
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
  double number_value(const Json& v, std::string_view key) const {
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
    const Json& v = at(key);
    if (!v.is_array()) return {number_value(v, key)};
    if (v.empty()) fail(key, "must not be empty");
    std::vector<double> out;
    for (const Json& item : v) out.push_back(number_value(item, key));
    return out;
  }

private:
  const SpecTree& tree_;
  const Json& value_;
  std::string path_;
};

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

std::string to_string(QuantityKind kind) {
  switch (kind) {
    case QuantityKind::albedo: return "albedo";
    case QuantityKind::vndf: return "vndf";
    case QuantityKind::scattering: return "scattering";
    case QuantityKind::validation: return "validation";
    case QuantityKind::masking: return "masking";
  }
  return "?";
}

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
  for (const Json& item : list) out.push_back(alpha_item(t, "alphas", item));
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

// ---- quantities ------------------------------------------------------------------------------------------

namespace {

QuantityKind quantity_kind(const Table& t) {
  const std::string kind = t.string("kind");
  for (QuantityKind k : {QuantityKind::albedo, QuantityKind::vndf, QuantityKind::scattering, QuantityKind::validation,
                         QuantityKind::masking})
    if (to_string(k) == kind) return k;
  t.fail("kind", fmt::format("{} is not a quantity (albedo, vndf, scattering, validation, masking)", quote_excerpt(kind)));
}

// The keys each kind takes, besides kind, material and surface.
std::vector<std::string> quantity_keys(QuantityKind kind) {
  std::vector<std::string> keys{"kind", "material", "surface"};
  const auto add = [&](std::initializer_list<const char*> more) { keys.insert(keys.end(), more.begin(), more.end()); };
  switch (kind) {
    case QuantityKind::albedo: add({"orders", "target_relative_error", "mus", "inside"}); break;
    case QuantityKind::vndf: add({"target_tv", "theta", "theta_range", "phi", "rows"}); break;
    case QuantityKind::scattering: add({"orders", "target_tv", "theta", "theta_range", "phi"}); break;
    case QuantityKind::validation:
      add({"sampler", "dump", "pdf", "above_horizon", "detect_tv", "power", "significance", "theta", "theta_range", "phi",
           "rows", "columns", "frame", "dropped", "transport", "masking"});
      break;
    case QuantityKind::masking:
      add({"what", "target_standard_error", "theta", "theta_range", "phi", "light_theta", "light_phi", "bins", "resolution",
           "realisations"});
      break;
  }
  return keys;
}

std::string target_key(QuantityKind kind) {
  if (kind == QuantityKind::albedo) return "target_relative_error";
  if (kind == QuantityKind::masking) return "target_standard_error";
  return kind == QuantityKind::validation ? "detect_tv" : "target_tv";
}

double quantity_target(const Table& t, QuantityKind kind) {
  const std::string key = target_key(kind);
  const double target = t.number(key);
  if (!(target > 0)) t.fail(key, fmt::format("{} must be > 0", target));
  if (kind == QuantityKind::masking && target >= 0.5)
    t.fail(key, fmt::format("{}: a standard error of a masking probability below 0.5", target));
  if (kind != QuantityKind::albedo && kind != QuantityKind::masking && target >= 1)
    t.fail(key, fmt::format("{}: a TV distance is below 1", target));
  if (kind == QuantityKind::albedo && target >= 0.5) t.fail(key, fmt::format("{}: a relative error below 0.5", target));
  return target;
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

// theta x phi; theta checked against the horizon: [0, 90) above it, (90, 180] (light from inside) only
// where `from_inside_ok`.
std::vector<Direction> quantity_directions(const Table& t, bool from_inside_ok) {
  const std::string theta_key = t.has("theta") ? "theta" : "theta_range";
  std::vector<Direction> out;
  for (double theta : theta_values(t)) {
    const bool above = theta >= 0 && theta < 90, inside = from_inside_ok && theta > 90 && theta <= 180;
    if (!above && !inside)
      t.fail(theta_key, fmt::format("theta {} deg is {} (this quantity takes [0, 90){})", theta,
                                    theta >= 90 && theta <= 180 ? "at or below the horizon" : "not an angle of a view",
                                    from_inside_ok ? ", or (90, 180] from inside a dielectric" : ""));
    for (double phi : t.has("phi") ? t.numbers("phi") : std::vector<double>{0.0}) out.push_back({theta, phi});
  }
  return out;
}

// A file named in a spec: as given when absolute, else in the spec's folder.
std::filesystem::path spec_file_path(const std::string& name, const std::filesystem::path& spec_dir) {
  return std::filesystem::path(name).is_absolute() ? std::filesystem::path(name) : spec_dir / name;
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

Orders quantity_orders(const Table& t) {
  const std::string orders = t.string("orders", "single");
  if (orders != "single" && orders != "all") t.fail("orders", fmt::format("{}: single or all", quote_excerpt(orders)));
  return orders == "single" ? Orders::single : Orders::all;
}

void check_albedo_material(const Table& t, const SpecMaterial& m, bool inside) {
  for (std::size_t i = 0; i < m.alphas.size(); ++i) {
    const auto [ax, ay] = m.alphas[i];
    if (ax != ay) t.fail("material", fmt::format("material {}: an albedo table is isotropic (alpha pair {}, {})", quote_excerpt(m.name), ax, ay));
    if (ax < kMinAlbedoAlpha || ax > kMaxAlbedoAlpha)
      t.fail("material", fmt::format("material {}: alpha {} outside an albedo table's [{}, {}]", quote_excerpt(m.name), ax,
                                     kMinAlbedoAlpha, kMaxAlbedoAlpha));
    if (i > 0 && !(ax > m.alphas[i - 1].first))
      t.fail("material", fmt::format("material {}: an albedo table's alphas must increase ({} after {})", quote_excerpt(m.name), ax,
                                     m.alphas[i - 1].first));
  }
  if (inside && !m.facet.transmits()) t.fail("inside", fmt::format("light from inside needs a dielectric ({} is opaque)", quote_excerpt(m.name)));
}

void read_zoo_sampler(const Table& t, SpecQuantity& q) {
  for (const char* key : {"pdf", "above_horizon", "columns", "frame", "dropped", "transport", "masking"})
    if (t.has(key)) t.fail(key, fmt::format("{} applies to a dump (a zoo sampler's density is its own)", key));
  q.sampler = t.string("sampler");
  if (find_sampler(q.sampler) == nullptr)
    t.fail("sampler", fmt::format("{} is not a sampler of the zoo ({})", quote_excerpt(q.sampler), fmt::join(sampler_names(), ", ")));
}

// What a dump holds besides its directions: columns, frame, and for a BSDF's samples its weights' convention.
void read_dump_layout(const Table& t, SpecQuantity& q, const SpecMaterial& m) {
  q.dump_columns = t.string("columns", "x,y,z");
  try {
    (void)SampleColumns::parse(q.dump_columns);
  } catch (const std::invalid_argument& e) {
    t.fail("columns", e.what());
  }
  q.dump_frame = t.string("frame", "z-up");
  if (q.dump_frame != "z-up" && q.dump_frame != "y-up")
    t.fail("frame", fmt::format("{} is not a frame (z-up, y-up)", quote_excerpt(q.dump_frame)));
  const bool bsdf = dump_has_bsdf(q);
  if (bsdf && m.facet.kind() == MaterialKind::lambertian)
    t.fail("material", fmt::format("material {}: a BSDF dump's material is a mirror, a conductor or a dielectric",
                                   quote_excerpt(m.name)));
  for (const char* key : {"transport", "masking"})
    if (t.has(key) && !bsdf) t.fail(key, fmt::format("{} is the convention of a BSDF's weights: give pdf = \"bsdf\" or "
                                                     "weight columns", key));
  try {
    if (t.has("transport")) q.convention.transport = parse_transport_mode("transport", t.string("transport"));
    if (t.has("masking")) q.convention.masking = parse_masking_form("masking", t.string("masking"));
  } catch (const std::invalid_argument& e) {
    t.fail(t.has("transport") ? "transport" : "masking", e.what());
  }
}

// A dump was sampled at one alpha and one view; its density is one the validator knows, or its material's BSDF.
void read_dump(const Table& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  const std::string name = t.string("dump");
  const std::filesystem::path path = spec_file_path(name, spec_dir);
  if (!std::filesystem::is_regular_file(path)) t.fail("dump", fmt::format("no sample file {}", quote_excerpt(path.string())));
  if (m.alphas.size() != 1 || q.directions.size() != 1)
    t.fail("dump", fmt::format("a dump is sampled at one alpha and one view (material {} has {} alpha(s), the quantity {} "
                               "view(s))", quote_excerpt(m.name), m.alphas.size(), q.directions.size()));
  q.dump = path.string();
  q.dump_pdf = t.string("pdf", "vndf");
  FilePdf pdf = FilePdf::vndf;
  try {
    pdf = parse_file_pdf(q.dump_pdf);
  } catch (const std::invalid_argument& e) {
    t.fail("pdf", e.what());
  }
  read_dump_layout(t, q, m);
  if (q.directions.front().theta_deg > 90 && !(dump_has_bsdf(q) && m.facet.transmits()))
    t.fail("theta", "a view below the surface is light from inside a dielectric: its dump needs pdf = \"bsdf\" (or "
                    "weight columns) and a dielectric material");
  q.above_horizon = t.boolean("above_horizon", false);
  if (q.above_horizon && !claims_reflected_directions(pdf))
    t.fail("above_horizon", fmt::format("pdf {} is a density of normals (none is below the horizon)", q.dump_pdf));
  if (t.has("dropped") && !q.above_horizon) t.fail("dropped", "dropped applies with above_horizon = true only");
  q.dump_dropped = std::uint64_t(t.integer("dropped", 0, 0, std::int64_t(1) << 53));
}

// ---- masking ----------------------------------------------------------------------------------------------

// `what`: one name or a list of g1, g2, conditional (default g1), each at most once.
MaskingWhat masking_what(const Table& t) {
  if (!t.has("what")) return {true, false, false};
  const Json& v = t.at("what");
  if (v.is_array() && v.empty()) t.fail("what", "must not be empty");
  MaskingWhat w;
  for (const Json& item : v.is_array() ? v : Json::array({v})) {
    if (!item.is_string()) t.fail("what", "a list of g1, g2, conditional");
    const std::string name = item.get<std::string>();
    bool* flag = name == "g1" ? &w.g1 : name == "g2" ? &w.g2 : name == "conditional" ? &w.conditional : nullptr;
    if (flag == nullptr) t.fail("what", fmt::format("{} is not a masking quantity (g1, g2, conditional)", quote_excerpt(name)));
    if (*flag) t.fail("what", fmt::format("{} is listed twice", name));
    *flag = true;
  }
  return w;
}

// G2's lights: light_theta (required with g2, in [0, 90)) x light_phi (default [0]); refused without g2.
std::vector<Direction> masking_lights(const Table& t, bool g2) {
  for (const char* key : {"light_theta", "light_phi"})
    if (!g2 && t.has(key)) t.fail(key, "lights apply to g2 (what = [\"g2\", ...])");
  if (!g2) return {};
  if (!t.has("light_theta")) t.fail("light_theta", "g2 needs its lights: light_theta = [...] (degrees; light_phi default [0])");
  std::vector<Direction> out;
  for (double theta : t.numbers("light_theta")) {
    if (!(theta >= 0 && theta < 90))
      t.fail("light_theta", fmt::format("theta {} deg is at or below the horizon or not an angle (a light takes [0, 90))", theta));
    for (double phi : t.has("light_phi") ? t.numbers("light_phi") : std::vector<double>{0.0}) out.push_back({theta, phi});
  }
  return out;
}

// The surface of a masking quantity: a built one (an assembly, or conditional masking on auto) takes a
// resolution; a heightmap is one surface (one alpha); an assembly is built to the material's NDF.
void check_masking_surface(const Table& t, SpecQuantity& q, const SpecMaterial& m) {
  const bool built = q.surface.kind == SurfaceChoice::Kind::assembly ||
                     (q.surface.kind == SurfaceChoice::Kind::automatic && q.masking.conditional);
  if (t.has("resolution") && !built)
    t.fail("resolution", q.surface.kind == SurfaceChoice::Kind::heightmap
                             ? "a heightmap has its own resolution"
                             : "the analytic Smith model has no surface (resolution applies to an assembly or to conditional masking)");
  q.resolution = int(t.integer("resolution", kDefaultMaskingResolution, kMinMaskingResolution, kMaxMaskingResolution));
  if ((q.resolution & (q.resolution - 1)) != 0) t.fail("resolution", fmt::format("{} must be a power of two", q.resolution));
  if (t.has("realisations") && !built)
    t.fail("realisations", q.surface.kind == SurfaceChoice::Kind::heightmap
                               ? "a heightmap is one realisation"
                               : "the analytic Smith model has no surface (realisations apply to an assembly or to conditional masking)");
  q.realisations = int(t.integer("realisations", 1, 1, kMaxMaskingRealisations));
  if (q.surface.kind == SurfaceChoice::Kind::heightmap && m.alphas.size() != 1)
    t.fail("surface", fmt::format("a heightmap is one surface: material {} must have one alpha (it has {})",
                                  quote_excerpt(m.name), m.alphas.size()));
  if (q.surface.kind != SurfaceChoice::Kind::assembly) return;
  if (microgeom::find_assembly(q.surface.name)->reference != m.ndf)
    t.fail("surface", fmt::format("assembly {} is built to {}, material {} is {}", q.surface.name,
                                  to_string(microgeom::find_assembly(q.surface.name)->reference),
                                  quote_excerpt(m.name), to_string(m.ndf)));
}

void read_masking(const Table& t, SpecQuantity& q, const SpecMaterial& m) {
  q.masking = masking_what(t);
  q.lights = masking_lights(t, q.masking.g2);
  if (t.has("bins") && !q.masking.conditional) t.fail("bins", "bins apply to conditional masking");
  q.bins = int(t.integer("bins", 10, 2, 100));
  check_masking_surface(t, q, m);
}

void read_kind_options(const Table& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  const bool view_kind = q.kind != QuantityKind::albedo;
  const bool inside_ok = (q.kind == QuantityKind::scattering || (q.kind == QuantityKind::validation && t.has("dump"))) &&
                         m.facet.transmits();
  if (view_kind) q.directions = quantity_directions(t, inside_ok);
  if (q.kind == QuantityKind::albedo || q.kind == QuantityKind::scattering) q.orders = quantity_orders(t);
  if (q.kind == QuantityKind::albedo) {
    q.mus = int(t.integer("mus", 16, kMinAlbedoMus, kMaxAlbedoMus));
    q.inside = t.boolean("inside", false);
    check_albedo_material(t, m, q.inside);
  }
  if (q.kind == QuantityKind::vndf || q.kind == QuantityKind::validation) {
    q.rows = int(t.integer("rows", 31, 3, kMaxBinningRows));
    if (q.rows % 2 == 0) t.fail("rows", fmt::format("{} must be odd", q.rows));
    if (m.ndf != NdfKind::ggx) t.fail("material", fmt::format("material {}: {} is for GGX (the ellipsoid oracle, the zoo)", quote_excerpt(m.name), to_string(q.kind)));
  }
  if (q.kind == QuantityKind::validation) {
    if (t.has("sampler") == t.has("dump"))
      t.fail("sampler", "give exactly one of sampler (a zoo sampler, drawn) and dump (a file of samples)");
    if (t.has("dump")) read_dump(t, q, m, spec_dir);
    else read_zoo_sampler(t, q);
    q.power = t.number("power", 0.9);
    q.significance = t.number("significance", 0.01);
    if (!(q.power > 0 && q.power < 1)) t.fail("power", fmt::format("{} must be in (0, 1)", q.power));
    if (!(q.significance > 0 && q.significance < 0.5)) t.fail("significance", fmt::format("{} must be in (0, 0.5)", q.significance));
  }
  if (q.kind == QuantityKind::masking) read_masking(t, q, m);
}

// A dump validated against its analytic reference needs no detect_tv: its rows are given, and they fix the TV
// detected (the plan states it). Against a surface it does: the tile is sized from it.
bool dump_detects_what_its_rows_do(const Table& t, const SpecQuantity& q) {
  return q.kind == QuantityKind::validation && t.has("dump") && !t.has("detect_tv") &&
         q.surface.kind == SurfaceChoice::Kind::automatic;
}

SpecQuantity read_quantity(const Table& t, const ExperimentSpec& spec, std::size_t index,
                           const std::filesystem::path& spec_dir) {
  SpecQuantity q;
  q.kind = quantity_kind(t);
  q.key = item_path("quantity", index);
  q.line = t.tree().line_of(q.key);
  t.only_keys(quantity_keys(q.kind), fmt::format("a{} {} quantity", q.kind == QuantityKind::albedo ? "n" : "", to_string(q.kind)));
  q.material = t.string("material");
  const auto m = std::find_if(spec.materials.begin(), spec.materials.end(), [&](const auto& x) { return x.name == q.material; });
  if (m == spec.materials.end()) t.fail("material", fmt::format("no material named {}", quote_excerpt(q.material)));
  q.surface = quantity_surface(t, spec_dir);
  q.target = dump_detects_what_its_rows_do(t, q) ? 0.0 : quantity_target(t, q.kind);
  read_kind_options(t, q, *m, spec_dir);
  return q;
}

}  // namespace

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

}  // namespace microsim::experiment
