// python: the tables the command line computes in one call: the energy tables of `microsim albedo` (its own
// layout, a renderer's layout with --layout, and the grade of a table with --grade) and the stability sweep of
// `microsim stability`, each returned as the dict its --json writes.
#include "python/binding.h"

#include "measure/albedo.h"
#include "microfacet/material.h"
#include "scatter/albedo_anisotropic.h"
#include "scatter/albedo_glass_grade.h"
#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_grade.h"
#include "scatter/albedo_layout.h"
#include "scatter/albedo_layout_io.h"
#include "scatter/albedo_table.h"
#include "scatter/albedo_table_io.h"
#include "validate/stability.h"

#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace microsim::python {

namespace {

struct AlbedoArguments {
  std::string model, ndf, material;
  bool inside = false;
  std::optional<std::vector<double>> alphas;
  int mus = 16;
  double tolerance = 1e-8;
  std::uint64_t paths = 0, seed = 0;
  int max_order = 0, resolution = 0, threads = 0;
};

constexpr int kDefaultMus = 16, kDefaultResolution = 512;
constexpr std::uint64_t kDefaultPaths = 1'000'000, kDefaultSeed = 1;

const AlbedoLayout& layout_named(const std::string& name) {
  try {
    return find_albedo_layout("layout", name);
  } catch (const std::invalid_argument& e) {  // ParseError: the names
    throw py::value_error(e.what());
  }
}

void check_threads(int threads) {
  if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores), got " + std::to_string(threads));
}

// The arguments a layout does not take are refused, as the command line refuses their options, when not at
// their defaults; the tolerance checked.
void check_layout_arguments(const AlbedoArguments& a) {
  if (a.model != "analytic")
    throw py::value_error("model '" + a.model + "': a layout table holds the analytic reference (model='analytic')");
  const auto refuse = [](bool given, const char* name) {
    if (given) throw py::value_error(std::string(name) + " does not apply to layout (the layout fixes its nodes)");
  };
  refuse(a.inside, "inside");
  refuse(a.alphas.has_value(), "alphas");
  refuse(a.mus != kDefaultMus, "mus");
  refuse(a.paths != kDefaultPaths, "paths");
  refuse(a.seed != kDefaultSeed, "seed");
  refuse(a.max_order != kDefaultMaxOrder, "max_order");
  refuse(a.resolution != kDefaultResolution, "resolution");
  if (!(a.tolerance >= 1e-13 && a.tolerance <= 1e-2))
    throw py::value_error("tolerance must be in [1e-13, 1e-2], got " + std::to_string(a.tolerance));
}

// `microsim albedo --layout L`: the analytic reference of a GGX (or, ndf='beckmann', a Beckmann) mirror in a
// renderer's layout.
py::object albedo_layout_of(const AlbedoLayout& layout, const AlbedoArguments& a, const py::object& progress) {
  if (a.material != "mirror")
    throw py::value_error("material '" + a.material + "': the renderers' layouts hold a mirror's E (F = 1): "
                          "material='mirror'");
  check_layout_arguments(a);
  const NdfKind ndf = parse_ndf_kind("ndf", a.ndf);  // ParseError: ValueError
  std::optional<LayoutTable> table;
  run_interruptible([&](const RunControl& run) {
    RunControl r = run;
    r.threads = a.threads;
    table = layout_table(layout, a.tolerance, r, true, ndf);
  }, progress);
  return json_object(layout_table_json(*table));
}

// `microsim albedo --layout cycles-glass|cycles-glass-inv --json`: a GGX dielectric over Cycles' index axis (the
// layout fixes the material's indices: material is refused).
py::object glass_layout_of(const GlassLayout& layout, const AlbedoArguments& a, const py::object& progress) {
  if (a.material != "mirror")
    throw py::value_error("material '" + a.material + "' does not apply to a glass layout (it fixes the indices)");
  if (a.ndf != "ggx") throw py::value_error("ndf does not apply to a glass layout (a GGX dielectric's)");
  check_layout_arguments(a);
  std::optional<GlassLayoutTable> table;
  run_interruptible([&](const RunControl& run) {
    RunControl r = run;
    r.threads = a.threads;
    table = glass_layout_table(layout, a.tolerance, r);
  }, progress);
  return json_object(glass_layout_json(*table));
}

// `compute` of a copy of `request` run with this call's RunControl (GIL released, Ctrl-C) on `threads`: its result.
template <class Request, class Compute>
auto run_request(const Request& request, int threads, const py::object& progress, Compute compute) {
  decltype(compute(request)) result;
  run_interruptible([&](const RunControl& run) {
    Request r = request;
    r.run = run;
    r.run.threads = threads;
    result = compute(r);
  }, progress);
  return result;
}

// `microsim albedo --model analytic --alphas AX,... --alphas-y AY,... --json`: the anisotropic mirror's table;
// the request checked by anisotropic_albedo_table (std::invalid_argument: ValueError).
py::object anisotropic_albedo_table_of(const std::vector<double>& alphas_x, const std::vector<double>& alphas_y,
                                       int mus, int phis, double tolerance, int threads, const py::object& progress) {
  check_threads(threads);
  AnisotropicAlbedoRequest r;
  r.alphas_x = alphas_x;
  r.alphas_y = alphas_y;
  r.mus = mus;
  r.phis = phis;
  r.tolerance = tolerance;
  const auto table = [](const AnisotropicAlbedoRequest& q) { return anisotropic_albedo_table(q); };
  return json_object(anisotropic_albedo_json(*run_request(r, threads, progress, table)));
}

// `microsim albedo`: E(mu, alpha) and its average per alpha; the request checked as the command line checks it.
py::object albedo_table_of(const std::string& model, const std::string& ndf, const std::string& material, bool inside,
                           const std::optional<std::vector<double>>& alphas, int mus, double tolerance,
                           std::uint64_t paths, std::uint64_t seed, int max_order, int resolution,
                           const std::string& walk_kernel, int threads, const std::optional<std::string>& layout,
                           const py::object& progress) {
  check_threads(threads);
  if (layout && walk_kernel != "scalar")
    throw py::value_error("walk_kernel does not apply to layout (an analytic table)");
  if (layout && find_glass_layout(*layout) != nullptr)
    return glass_layout_of(*find_glass_layout(*layout), {model, ndf, material, inside, alphas, mus, tolerance, paths,
                                                         seed, max_order, resolution, threads}, progress);
  if (layout)
    return albedo_layout_of(layout_named(*layout), {model, ndf, material, inside, alphas, mus, tolerance, paths, seed,
                                                    max_order, resolution, threads}, progress);
  AlbedoTableRequest r;
  r.model = parse_albedo_model("model", model);
  r.ndf = parse_ndf_kind("ndf", ndf);
  r.material = parse_material("material", material);
  r.inside = inside;
  if (alphas) r.alphas = *alphas;
  r.mus = mus;
  r.tolerance = tolerance;
  r.paths = paths;
  r.seed = seed;
  r.max_order = max_order;
  r.resolution = resolution;
  r.walk_kernel = parse_walk_kernel("walk_kernel", walk_kernel);
  check_albedo_request(r);  // std::invalid_argument (lanes: GGX smith-walk only): ValueError
  const auto table = [](const AlbedoTableRequest& q) { return std::optional<AlbedoTable>(measure_albedo_table(q)); };
  return json_object(albedo_table_json(*run_request(r, threads, progress, table)));
}

// `microsim albedo --grade TABLE --layout cycles-glass|cycles-glass-inv`: the dict its --json writes, plus
// "exit_code".
py::object grade_glass_table_of(const std::string& file, const GlassLayout& layout, double tolerance,
                                 std::uint64_t table_samples, int threads, const py::object& progress) {
  std::vector<double> values;
  try {
    values = read_glass_values(file, layout);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(file + ": " + e.what());
  }
  for (std::size_t k = 0; k < values.size(); ++k)
    if (!std::isfinite(values[k])) throw py::value_error(file + ": value " + std::to_string(k) + " is not finite");
  std::optional<GlassGrade> grade;
  run_interruptible([&](const RunControl& run) {
    RunControl r = run;
    r.threads = threads;
    grade = grade_glass_table(layout, values, tolerance, table_samples, r);
  }, progress);
  py::object out = json_object(glass_grade_json(*grade));
  out["exit_code"] = grade->passed() ? 0 : 1;
  return out;
}

// `microsim albedo --grade TABLE --layout L`: the dict its --json writes, plus "exit_code" (0 every graded node
// within the tolerance, 1 not). A file that cannot be read or is not a table in the layout: ValueError.
py::object grade_albedo_table_of(const py::object& path, const std::string& layout, const std::string& ndf,
                                 double tolerance, std::optional<std::uint64_t> table_samples, int threads,
                                 const py::object& progress) {
  check_threads(threads);
  const NdfKind kind = parse_ndf_kind("ndf", ndf);  // ParseError: ValueError
  if (!(tolerance >= 1e-13 && tolerance <= 1e-2))
    throw py::value_error("tolerance must be in [1e-13, 1e-2], got " + std::to_string(tolerance));
  if (table_samples && *table_samples < 1) throw py::value_error("table_samples must be >= 1 (None: not stated)");
  const std::string file = py::module_::import("os").attr("fsdecode")(path).cast<std::string>();
  if (const GlassLayout* glass = find_glass_layout(layout)) {
    if (kind != NdfKind::ggx) throw py::value_error("ndf does not apply to a glass layout (a GGX dielectric's)");
    return grade_glass_table_of(file, *glass, tolerance, table_samples.value_or(0), threads, progress);
  }
  const AlbedoLayout& l = layout_named(layout);
  LayoutValues v;
  try {
    v = read_layout_channels(file, l);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(file + ": " + e.what());
  }
  for (const std::vector<double>* channel : {&v.values, &v.grazing})
    for (std::size_t k = 0; k < channel->size(); ++k)
      if (!std::isfinite((*channel)[k])) throw py::value_error(file + ": value " + std::to_string(k) + " is not finite");
  std::optional<std::vector<AlbedoGrade>> grades;
  run_interruptible([&](const RunControl& run) {
    RunControl r = run;
    r.threads = threads;
    grades = grade_albedo_channels(l, v.values, v.grazing, tolerance, table_samples.value_or(0), r, kind);
  }, progress);
  nlohmann::json j = albedo_grade_json(grades->front());
  if (grades->size() > 1) j["grazing"] = albedo_grade_json(grades->back());
  py::object out = json_object(j);
  bool passed = true;
  for (const AlbedoGrade& g : *grades) passed = passed && g.passed();
  out["exit_code"] = passed ? 0 : 1;
  return out;
}

// `microsim stability`: the whole sweep of the zoo and the analytic functions (its "violations": the rows
// over their bound; the command line exits 1 when it is not 0).
py::object stability_of(int threads, const py::object& progress) {
  check_threads(threads);
  std::optional<StabilityTable> table;
  run_interruptible([&](const RunControl& run) {
    StabilityRun s;
    s.run = run;
    s.run.threads = threads;
    table = run_stability_sweep(StabilityGrid::standard(), sampler_registry(), /*include_functions=*/true, s);
  }, progress);
  return json_object(stability_table_json(*table));
}

}  // namespace

void bind_tables(py::module_& m) {
  using namespace pybind11::literals;
  m.def("albedo_table", &albedo_table_of, py::kw_only(), "model"_a = "analytic", "ndf"_a = "ggx", "material"_a = "mirror",
        "inside"_a = false, "alphas"_a = py::none(), "mus"_a = 16, "tolerance"_a = 1e-8, "paths"_a = 1'000'000,
        "seed"_a = 1, "max_order"_a = kDefaultMaxOrder, "resolution"_a = 512, "walk_kernel"_a = "scalar", "threads"_a = 0,
        "layout"_a = py::none(), "progress"_a = py::none(),
        R"(The energy table of `microsim albedo`: E(mu, alpha) at Gauss-Legendre mus and its hemispherical average.

model: 'analytic' (single scattering by quadrature, to `tolerance`), 'smith-walk' or 'surface' (sampled with
`paths` per cell); ndf: 'ggx' or 'beckmann'; material: 'mirror' or 'dielectric:ETA' (inside: light from inside);
alphas: increasing, in [0.005, 2] (default 0.1, 0.25, 0.5, 0.75, 1); walk_kernel: 'scalar' or 'lanes' (smith-walk
with GGX: `albedo --walk-kernel`). Returns the dict `albedo --json` writes.
layout: 'cycles', 'filament-dfg', 'enterprise-pbr' or 'uniform' (`albedo --layout`): the analytic E of a GGX
mirror (ndf='beckmann': a Beckmann mirror) at the layout's nodes with its errors, E_avg where the renderer ships
it and the layout's interpolation error at cell centres (the layout fixes the nodes: only ndf, tolerance and
threads apply); 'cycles-glass' or
'cycles-glass-inv': a GGX dielectric's E = E_R + E_T over Cycles' 16 x 16 x 16 rough-glass grid (roughness, mu,
index), with E_avg (the layout fixes the indices too: material does not apply).)");
  m.def("anisotropic_albedo_table", &anisotropic_albedo_table_of, py::kw_only(), "alphas_x"_a, "alphas_y"_a,
        "mus"_a = 16, "phis"_a = 8, "tolerance"_a = 1e-8, "threads"_a = 0, "progress"_a = py::none(),
        R"(The anisotropic GGX mirror's table (`microsim albedo --model analytic --alphas AX,... --alphas-y AY,...`):
E(mu, phi) per (alpha_x, alpha_y), analytic single scattering with errors, on Gauss-Legendre nodes in mu (mus)
and phi on [0, pi/2] (phis, 1..64; phi from the alpha_x axis), and E_avg. alphas in [0.005, 2]. Returns the
dict `--json` writes (E nested [alpha_x][alpha_y][mu][phi], E_avg [alpha_x][alpha_y]).)");
  m.def("grade_albedo_table", &grade_albedo_table_of, "path"_a, py::kw_only(), "layout"_a, "ndf"_a = "ggx",
        "tolerance"_a = 1e-4, "table_samples"_a = py::none(), "threads"_a = 0, "progress"_a = py::none(),
        R"(The grade of a table in a renderer's layout (`microsim albedo --grade PATH --layout L`): path an .exr or the
.csv microsim writes (a glass layout, 'cycles-glass' or 'cycles-glass-inv': the .csv, or the .txt of values as
Cycles prints them; Filament's: both channels, DFG.x under "grazing", when the file has it); each node against the analytic reference (of a GGX mirror, or ndf='beckmann' a Beckmann mirror's), within the encoding's quantisation, within the
noise of table_samples samples per node (when stated), and within tolerance. Returns the dict `--json` writes
("passed", "failed", "max_abs", "rms", "cells"...) plus "exit_code" (the command line's: 0 pass, 1 fail).)");
  m.def("stability", &stability_of, py::kw_only(), "threads"_a = 0, "progress"_a = py::none(),
        R"(The stability sweep of `microsim stability`: every sampler (float and double) and analytic function at the
extremes. Returns the dict `stability --json` writes ("violations": the rows over their bound; 0 passes).)");
}

}  // namespace microsim::python
