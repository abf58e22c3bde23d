// python: the tables the command line computes in one call: the energy tables of `microsim albedo` and the
// stability sweep of `microsim stability`, each returned as the dict its --json writes.
#include "python/binding.h"

#include "microfacet/material.h"
#include "scatter/albedo_table.h"
#include "scatter/albedo_table_io.h"
#include "validate/stability.h"

#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace microsim::python {

namespace {

py::object json_object(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

// `microsim albedo`: E(mu, alpha) and its average per alpha; the request checked as the command line checks it.
py::object albedo_table_of(const std::string& model, const std::string& ndf, const std::string& material, bool inside,
                           const std::optional<std::vector<double>>& alphas, int mus, double tolerance,
                           std::uint64_t paths, std::uint64_t seed, int max_order, int resolution, int threads,
                           const py::object& progress) {
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
  if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores), got " + std::to_string(threads));
  check_albedo_request(r);  // std::invalid_argument: ValueError
  std::optional<AlbedoTable> table;
  run_interruptible([&](const RunControl& run) {
    AlbedoTableRequest request = r;
    request.run = run;
    request.run.threads = threads;
    table = albedo_table(request);
  }, progress);
  return json_object(albedo_table_json(*table));
}

// `microsim stability`: the whole sweep of the zoo and the analytic functions (its "violations": the rows
// over their bound; the command line exits 1 when it is not 0).
py::object stability_of(int threads, const py::object& progress) {
  if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores), got " + std::to_string(threads));
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
        "seed"_a = 1, "max_order"_a = kDefaultMaxOrder, "resolution"_a = 512, "threads"_a = 0, "progress"_a = py::none(),
        R"(The energy table of `microsim albedo`: E(mu, alpha) at Gauss-Legendre mus and its hemispherical average.

model: 'analytic' (single scattering by quadrature, to `tolerance`), 'smith-walk' or 'surface' (sampled with
`paths` per cell); ndf: 'ggx' or 'beckmann'; material: 'mirror' or 'dielectric:ETA' (inside: light from inside);
alphas: increasing, in [0.005, 2] (default 0.1, 0.25, 0.5, 0.75, 1). Returns the dict `albedo --json` writes.)");
  m.def("stability", &stability_of, py::kw_only(), "threads"_a = 0, "progress"_a = py::none(),
        R"(The stability sweep of `microsim stability`: every sampler (float and double) and analytic function at the
extremes. Returns the dict `stability --json` writes ("violations": the rows over their bound; 0 passes).)");
}

}  // namespace microsim::python
