// python: microsim.check_bsdf, the battery of measure/bsdf_battery.h on a BSDF given as vectorised numpy
// callables (what `microsim check-bsdf --plugin` runs on a C plugin). The callables run on the calling thread
// with the GIL held; Python's signal handlers run between batches (Ctrl-C: KeyboardInterrupt).
#include "binding.h"

#include "core/atomic_file.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_battery_html.h"
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

BsdfUnderTest under_test(const py::function& sample, const py::function& eval, const py::object& pdf, int channels,
                         const BsdfConvention& convention, bool stochastic_eval) {
  BsdfUnderTest b;
  b.name = "Python callables";
  b.channels = channels;
  b.convention = convention;
  b.stochastic_eval = stochastic_eval;
  const std::size_t c = std::size_t(channels);
  const bool pdf_known = !pdf.is_none();
  b.sample = [sample, c, pdf_known](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
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
      bool weighs = false;  // without pdf(), a sample whose weights are all 0 is lost
      for (std::size_t k = 0; k < c; ++k) weighs = weighs || weight[c * i + k] != 0;
      kept[i] = (unsigned char)(pdf_known ? pdfs[i] != 0 : weighs);  // a pdf of 0: a lost sample
    }
  };
  b.eval = [eval, c](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> value) {
    check_signals();
    copy_rows(eval(directions_array(wi), directions_array(wo)), wi.size(), c, value, "eval");
  };
  if (!pdf_known) return b;
  b.pdf = [pdf](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> out) {
    check_signals();
    copy_rows(pdf(directions_array(wi), directions_array(wo)), wi.size(), 1, out, "pdf");
  };
  return b;
}

// The keyword options of check_bsdf, as `check-bsdf` takes them.
struct PyBatteryArgs {
  std::string bsdf, transport, masking, arithmetic, reference;
  py::object alpha, views, html;
  int channels = 1;
  bool stochastic_eval = false;
  std::uint64_t samples = 200'000, seed = 1;
  double level = 0.01;
};

BatteryReference reference_of(const std::string& text) {
  if (text == "single-scattering") return BatteryReference::single_scattering;
  if (text == "smith-walk") return BatteryReference::smith_walk;
  if (text == "none") return BatteryReference::none;
  throw py::value_error(fmt::format("reference '{}': 'single-scattering', 'smith-walk' or 'none'", text));
}

// views: None (the default grid), or a sequence of THETA or (THETA, PHI) in degrees.
std::vector<BatteryView> views_of(const py::object& views) {
  std::vector<BatteryView> out;
  if (views.is_none()) return out;
  for (const py::handle v : views) {
    if (py::isinstance<py::float_>(v) || py::isinstance<py::int_>(v)) {
      out.push_back({v.cast<double>(), 0.0});
      continue;
    }
    const auto pair = v.cast<std::vector<double>>();
    if (pair.size() != 2) throw py::value_error("views: each a THETA or a (THETA, PHI) pair, in degrees");
    out.push_back({pair[0], pair[1]});
  }
  if (out.empty()) throw py::value_error("views: at least one (None for the default grid)");
  return out;
}

BatteryOptions options_of(const PyBatteryArgs& a) {
  if (a.arithmetic != "float32" && a.arithmetic != "float64") throw py::value_error("arithmetic: 'float32' or 'float64'");
  if (!(a.level > 0 && a.level < 1)) throw py::value_error(fmt::format("level {}: must be in (0, 1)", a.level));
  if (a.samples < 1000) throw py::value_error(fmt::format("samples {}: at least 1000 per view", a.samples));
  BatteryOptions o;
  o.samples = a.samples;
  o.seed = a.seed;
  o.level = a.level;
  o.arithmetic = a.arithmetic == "float64" ? Precision::float64 : Precision::float32;
  o.reference = reference_of(a.reference);
  o.views = views_of(a.views);
  return o;
}

py::object check_bsdf(const py::function& sample, const py::function& eval, const py::object& pdf, const PyBatteryArgs& a) {
  const Material claimed = parse_material("bsdf", a.bsdf);
  if (claimed.kind() == MaterialKind::lambertian) throw py::value_error("bsdf: mirror, conductor:ETA,K or dielectric:ETA");
  BsdfConvention convention;
  convention.transport = parse_transport_mode("transport", a.transport);
  convention.masking = parse_masking_form("masking", a.masking);
  const BatteryOptions o = options_of(a);
  if (o.reference == BatteryReference::single_scattering && (a.stochastic_eval || pdf.is_none()))
    throw py::value_error("reference 'single-scattering' needs a deterministic eval and a pdf (reference 'smith-walk' "
                          "or 'none')");
  const std::string html = a.html.is_none() ? std::string() : py::str(a.html).cast<std::string>();
  const GGX<double> ggx = ggx_of(a.alpha);
  const BatteryReport r = run_bsdf_battery(under_test(sample, eval, pdf, a.channels, convention, a.stochastic_eval),
                                           claimed, ggx, o);
  nlohmann::json j = to_json(r);
  j.update({{"passed", r.passed}, {"bsdf", a.bsdf}, {"alpha", py::str(a.alpha).cast<std::string>()}, {"level", a.level}});
  if (!html.empty())
    write_file_atomically(html, battery_html(r, "microsim.check_bsdf: Python callables",
                                             {"claims: " + a.bsdf + ", GGX alpha " + j["alpha"].get<std::string>() +
                                                  ", reference " + a.reference,
                                              fmt::format("{} samples per view, seed {}, level {} (Sidak over the "
                                                          "statistical tests)", a.samples, a.seed, a.level)}));
  return py::module_::import("json").attr("loads")(j.dump());
}

}  // namespace

void bind_battery(py::module_& m) {
  using namespace pybind11::literals;
  m.def(
      "check_bsdf",
      [](const py::function& sample, const py::function& eval, const py::object& pdf, const std::string& bsdf,
         const py::object& alpha, int channels, const std::string& transport, const std::string& masking,
         std::uint64_t samples, std::uint64_t seed, double level, const std::string& arithmetic,
         const std::string& reference, const py::object& views, bool stochastic_eval, const py::object& html) {
        return check_bsdf(sample, eval, pdf,
                          {bsdf, transport, masking, arithmetic, reference, alpha, views, html, channels, stochastic_eval,
                           samples, seed, level});
      },
      R"(Runs the whole BSDF battery (what `microsim check-bsdf` runs on a C plugin) on a BSDF
given as vectorised numpy callables, against the BSDF it claims (`bsdf`, `alpha`):
  sample(wi (n, 3), u (n, 3)) -> (wo (n, 3), pdf (n,), weight (n,) or (n, channels)); pdf 0 marks a lost sample
    (without a pdf callable, a weight of 0 in every channel);
  eval(wi (n, 3), wo (n, 3)) -> f(wi, wo) |cos wo|, (n,) or (n, channels);
  pdf(wi (n, 3), wo (n, 3)) -> (n,), or None (a sampler whose density is not known in closed form).
Directions z-up, wi the direction given (the camera side in radiance transport). The options are check-bsdf's:
reference 'single-scattering' (the exact BSDF of `bsdf`), 'smith-walk' (the Smith walk's multiple scattering) or
'none' (only the tests against itself); views None (the default grid; anisotropic alpha: views off the axes too)
or a list of THETA or (THETA, PHI) in degrees; stochastic_eval (eval an unbiased noisy estimate: averaged over
repeated calls); samples per view; level (family-wise, Sidak); html a path for the HTML report. Returns the
report as a dict (the JSON of `check-bsdf --json`): "verdict" ("pass" or "fail"), "passed", "tests" (one per
view's sampling and consistency, and the eval check), "eval" (the worst pairs), "bsdf", "alpha", "level".)",
      "sample"_a, "eval"_a, "pdf"_a = py::none(), py::kw_only(), "bsdf"_a, "alpha"_a, "channels"_a = 1,
      "transport"_a = "radiance", "masking"_a = "height-correlated", "samples"_a = 200'000, "seed"_a = 1,
      "level"_a = 0.01, "arithmetic"_a = "float32", "reference"_a = "single-scattering", "views"_a = py::none(),
      "stochastic_eval"_a = false, "html"_a = py::none());
}

}  // namespace microsim::python
