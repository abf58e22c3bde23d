// python: microsim.check_bsdf, the battery of measure/bsdf_battery.h on a BSDF given as vectorised numpy
// callables (what `microsim check-bsdf --plugin` runs on a C plugin). The callables run on the calling thread
// with the GIL held; Python's signal handlers run between batches (Ctrl-C: KeyboardInterrupt).
#include "binding.h"

#include "measure/bsdf_battery.h"
#include "microfacet/material.h"

#include <pybind11/stl.h>

#include <fmt/core.h>

namespace microsim::python {

namespace {

using Rows = py::array_t<double, py::array::c_style | py::array::forcecast>;

py::array_t<double> directions_array(std::span<const Vec3<double>> w) {
  py::array_t<double> a({py::ssize_t(w.size()), py::ssize_t(3)});
  auto m = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < w.size(); ++i)
    for (int k = 0; k < 3; ++k) m(py::ssize_t(i), k) = w[i][k];
  return a;
}

// A returned array of n rows of `columns` values (a vector for one column), copied out; ValueError naming `what`.
void copy_rows(const py::handle& value, std::size_t n, std::size_t columns, std::span<double> out, const char* what) {
  const Rows a = Rows::ensure(value);
  if (!a || std::size_t(a.size()) != n * columns || (a.ndim() != 1 && a.ndim() != 2) || std::size_t(a.shape(0)) != n)
    throw py::value_error(fmt::format("check_bsdf: {} must return {} rows of {} value(s)", what, n, columns));
  std::copy(a.data(), a.data() + n * columns, out.begin());
}

void check_signals() {
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

BsdfUnderTest under_test(const py::function& sample, const py::function& eval, const py::function& pdf, int channels,
                         const BsdfConvention& convention) {
  BsdfUnderTest b;
  b.name = "Python callables";
  b.channels = channels;
  b.convention = convention;
  const std::size_t c = std::size_t(channels);
  b.sample = [sample, c](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                         std::span<double> pdfs, std::span<double> weight, std::span<unsigned char> kept) {
    check_signals();
    const std::size_t n = wi.size();
    py::array_t<double> uu({py::ssize_t(n), py::ssize_t(3)});
    std::copy(u.begin(), u.end(), uu.mutable_data());
    const py::tuple r = sample(directions_array(wi), uu);
    if (r.size() != 3) throw py::value_error("check_bsdf: sample must return (wo, pdf, weight)");
    std::vector<double> out(3 * n);
    copy_rows(r[0], n, 3, out, "sample's wo");
    copy_rows(r[1], n, 1, pdfs, "sample's pdf");
    copy_rows(r[2], n, c, weight, "sample's weight");
    for (std::size_t i = 0; i < n; ++i) {
      wo[i] = Vec3<double>(out[3 * i], out[3 * i + 1], out[3 * i + 2]);
      kept[i] = (unsigned char)(pdfs[i] != 0);  // a pdf of 0: a lost sample
    }
  };
  b.eval = [eval, c](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> value) {
    check_signals();
    copy_rows(eval(directions_array(wi), directions_array(wo)), wi.size(), c, value, "eval");
  };
  b.pdf = [pdf](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> out) {
    check_signals();
    copy_rows(pdf(directions_array(wi), directions_array(wo)), wi.size(), 1, out, "pdf");
  };
  return b;
}

py::object check_bsdf(const py::function& sample, const py::function& eval, const py::function& pdf, const std::string& bsdf,
                      const py::handle& alpha, int channels, const std::string& transport, const std::string& masking,
                      std::uint64_t samples, std::uint64_t seed, double level, const std::string& arithmetic) {
  const Material claimed = parse_material("bsdf", bsdf);
  BsdfConvention convention;
  convention.transport = parse_transport_mode("transport", transport);
  convention.masking = parse_masking_form("masking", masking);
  if (arithmetic != "float32" && arithmetic != "float64") throw py::value_error("arithmetic: 'float32' or 'float64'");
  if (!(level > 0 && level < 1)) throw py::value_error(fmt::format("level {}: must be in (0, 1)", level));
  if (samples < 1000) throw py::value_error(fmt::format("samples {}: at least 1000 per view", samples));
  BatteryOptions o;
  o.samples = samples;
  o.seed = seed;
  o.level = level;
  o.arithmetic = arithmetic == "float64" ? Precision::float64 : Precision::float32;
  const BatteryReport r = run_bsdf_battery(under_test(sample, eval, pdf, channels, convention), claimed, ggx_of(alpha), o);
  nlohmann::json j = to_json(r);
  j["passed"] = r.passed;
  return py::module_::import("json").attr("loads")(j.dump());
}

}  // namespace

void bind_battery(py::module_& m) {
  using namespace pybind11::literals;
  m.def("check_bsdf", &check_bsdf, R"(Runs the whole BSDF battery (what `microsim check-bsdf` runs on a C plugin) on a BSDF
given as vectorised numpy callables, against the exact single-scattering BSDF it claims (`bsdf`, `alpha`):
  sample(wi (n, 3), u (n, 3)) -> (wo (n, 3), pdf (n,), weight (n,) or (n, channels)); pdf 0 marks a lost sample;
  eval(wi (n, 3), wo (n, 3)) -> f(wi, wo) |cos wo|, (n,) or (n, channels);
  pdf(wi (n, 3), wo (n, 3)) -> (n,).
Directions z-up, wi the direction given (the camera side in radiance transport). Returns the report as a dict
(the JSON of `check-bsdf --json`): "verdict" ("pass" or "fail"), "passed", "tests" (one per view's sampling and
consistency, and the eval check), "eval" (the worst pairs).)",
        "sample"_a, "eval"_a, "pdf"_a, py::kw_only(), "bsdf"_a, "alpha"_a, "channels"_a = 1, "transport"_a = "radiance",
        "masking"_a = "height-correlated", "samples"_a = 200'000, "seed"_a = 1, "level"_a = 0.01, "arithmetic"_a = "float32");
}

}  // namespace microsim::python
