// python: microsim.check_bsdf, the battery of measure/bsdf_battery.h on a BSDF given as vectorised numpy
// callables (what `microsim check-bsdf --plugin` runs on a C plugin). The callables run on the calling thread
// with the GIL held; Python's signal handlers run between batches (Ctrl-C: KeyboardInterrupt).
// microsim.check_bsdf_files, one BSDF's consistency with itself from a sample dump and an eval file
// (measure/bsdf_file_check.h, what `microsim check-bsdf-files` runs), on files or on arrays holding their rows,
// with the GIL released on a worker thread (run_interruptible).
#include "binding.h"

#include "core/atomic_file.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_battery_html.h"
#include "measure/bsdf_file_check.h"
#include "microfacet/material.h"

#include <pybind11/stl.h>

#include <fmt/core.h>

#include <cmath>
#include <optional>

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
  std::string bsdf, transport, masking, sampling, arithmetic, reference;
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
  convention.normals = parse_sampled_normals("sampling", a.sampling);
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
  return json_object(j);
}


// ---- check_bsdf_files --------------------------------------------------------------------------------------------

// The keyword options of check_bsdf_files, as `check-bsdf-files` takes them.
struct PyFilesArgs {
  std::string columns, eval_columns, frame;
  py::object cells, albedo;
  double theta = 0, phi = 0, level = 0.01;
  std::uint64_t lost = 0;
};

// The rows of argument `what`: a path (str or os.PathLike) of a file, or a float32/float64 array (N, columns)
// holding the rows such a file would (read in place while `keep` holds it).
BsdfRows rows_of(const py::handle& value, const char* what, int columns, std::vector<py::array>& keep) {
  if (py::isinstance<py::str>(value) || py::hasattr(value, "__fspath__"))
    return BsdfRows(std::filesystem::path(py::module_::import("os").attr("fsdecode")(value).cast<std::string>()));
  const py::array a = checked_array(value, what, columns, true);
  SampleArray rows;
  rows.name = std::string("the array ") + what;
  rows.rows = std::uint64_t(a.shape(0));
  for (int c = 0; c < columns; ++c) rows.columns.push_back(column_of(a, c));
  keep.push_back(a);
  return BsdfRows(std::move(rows));
}

// What the report names rows by: the file's path, or "array (N, K)".
std::string rows_name(const BsdfRows& rows) {
  return rows.array ? fmt::format("array ({}, {})", rows.array->rows, rows.array->columns.size()) : rows.path.string();
}

// The options, checked as the command line checks them (ValueError naming the argument and its value).
BsdfFileCheckOptions files_options(const PyFilesArgs& a) {
  if (!(a.theta >= 0 && a.theta <= 180))
    throw py::value_error(fmt::format("theta {}: must be in [0, 180] degrees", a.theta));
  if (!std::isfinite(a.phi)) throw py::value_error(fmt::format("phi {}: must be finite", a.phi));
  if (!(a.level > 0 && a.level < 1)) throw py::value_error(fmt::format("level {}: must be in (0, 1)", a.level));
  if (a.frame != "z-up" && a.frame != "y-up")
    throw py::value_error(fmt::format("frame '{}': 'z-up' or 'y-up'", a.frame));
  BsdfFileCheckOptions o;
  o.frame = a.frame == "y-up" ? SampleFrame::y_up : SampleFrame::z_up;
  o.lost = a.lost;
  o.level = a.level;
  if (!a.albedo.is_none()) {
    o.albedo = a.albedo.cast<double>();
    if (!(*o.albedo >= 0 && *o.albedo <= 10))
      throw py::value_error(fmt::format("albedo {}: must be in [0, 10]", *o.albedo));
  }
  return o;
}

py::object check_bsdf_files(const py::handle& dump, const py::handle& eval, const PyFilesArgs& a) {
  SampleColumns dc;
  EvalColumns ec;
  try {
    dc = SampleColumns::parse(a.columns);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(fmt::format("columns '{}': {}", a.columns, e.what()));
  }
  if (const std::string p = dump_columns_problem(dc); !p.empty())
    throw py::value_error(fmt::format("columns '{}': {}", a.columns, p));
  try {
    ec = EvalColumns::parse(a.eval_columns);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(fmt::format("eval_columns: {}", e.what()));
  }
  if (const std::string p = eval_columns_problem(ec); !p.empty())
    throw py::value_error(fmt::format("eval_columns '{}': {}", a.eval_columns, p));
  BsdfFileCheckOptions o = files_options(a);
  std::vector<py::array> keep;  // the arrays read in place, alive until the check returns
  const int eval_width = ec.wi_columns(dc.channels()).count;
  const BsdfRows d = rows_of(dump, "dump", dc.count, keep), e = rows_of(eval, "eval", eval_width, keep);
  if (!a.cells.is_none()) o.cells = rows_of(a.cells, "cells", eval_width, keep);
  const Vec3<double> wi = direction_from_degrees(a.theta, a.phi);
  std::optional<BatteryReport> r;
  run_interruptible([&](const RunControl& run) {
    BsdfFileCheckOptions with_run = o;
    with_run.run = run;
    r = microsim::check_bsdf_files(d, dc, e, ec, wi, with_run);
  }, py::none());
  nlohmann::json j = to_json(*r);  // as `check-bsdf-files --json` writes it, and "passed"
  j.update({{"dump", rows_name(d)}, {"eval", rows_name(e)}, {"theta", a.theta}, {"phi", a.phi},
            {"level", a.level}, {"passed", r->passed}});
  if (!a.cells.is_none()) j["cells"] = rows_name(o.cells);
  return json_object(j);
}

void bind_files(py::module_& m) {
  using namespace pybind11::literals;
  m.def(
      "check_bsdf_files",
      [](const py::handle& dump, const py::handle& eval, double theta, double phi, const py::object& cells,
         const std::string& columns, const std::string& eval_columns, const std::string& frame, std::uint64_t lost,
         const py::object& albedo, double level) {
        return check_bsdf_files(dump, eval, {columns, eval_columns, frame, cells, albedo, theta, phi, level, lost});
      },
      R"doc(One BSDF's consistency with itself from files (what `microsim check-bsdf-files` runs): a sample dump of
one view and an eval file of the same BSDF at the same rows.
dump: the path (str or os.PathLike) of a sample dump (.npy or text, as `validate --from` reads it), or a float32 /
  float64 array (N, K) of its rows; `columns` names its K columns (default x,y,z,pdf,weight: a weight per channel).
eval: the path of the eval file at the dump's rows (wi = the view, wo = the dump's direction, f(wi, wo) |cos wo|
  per channel, pdf(wo | wi)), or an array of its rows; `eval_columns` names them (default wi,wo,value,pdf).
theta, phi: the view in degrees (theta > 90: from inside). cells: the eval file (or array) at the view's cell
points, as `bsdf-queries --cells` writes them (adds the density, integral and furnace cell tests). frame: 'z-up' or
'y-up' (every file). lost: samples the dump leaves out (they weigh 0 in the furnace). albedo: the albedo the BSDF
claims at this view (1: energy conserving). level: family-wise (Sidak over the statistical tests).
Each weight is tested against eval / pdf and each pdf against the eval file's (1e-3 relative), and the white furnace.
Returns the report as a dict (the JSON of `check-bsdf-files --json`): "verdict" ("pass" or "fail"), "passed",
"tests" (test, view, p, passed, detail), "dump", "eval", "theta", "phi", "level" (and "cells"); an array stands as
"array (N, K)" for its path. Rows that do not match (counts, wi not the view, wo not the dump's direction) raise
ValueError, as the command line exits 2.)doc",
      "dump"_a, "eval"_a, py::kw_only(), "theta"_a, "phi"_a = 0.0, "cells"_a = py::none(),
      "columns"_a = "x,y,z,pdf,weight", "eval_columns"_a = "wi,wo,value,pdf", "frame"_a = "z-up", "lost"_a = 0,
      "albedo"_a = py::none(), "level"_a = 0.01);
}

}  // namespace

void bind_battery(py::module_& m) {
  using namespace pybind11::literals;
  bind_files(m);
  m.def(
      "check_bsdf",
      [](const py::function& sample, const py::function& eval, const py::object& pdf, const std::string& bsdf,
         const py::object& alpha, int channels, const std::string& transport, const std::string& masking,
         const std::string& sampling, std::uint64_t samples, std::uint64_t seed, double level, const std::string& arithmetic,
         const std::string& reference, const py::object& views, bool stochastic_eval, const py::object& html) {
        return check_bsdf(sample, eval, pdf,
                          {bsdf, transport, masking, sampling, arithmetic, reference, alpha, views, html, channels,
                           stochastic_eval,
                           samples, seed, level});
      },
      R"(Runs the whole BSDF battery (what `microsim check-bsdf` runs on a C plugin) on a BSDF
given as vectorised numpy callables, against the BSDF it claims (`bsdf`, `alpha`):
  sample(wi (n, 3), u (n, 3)) -> (wo (n, 3), pdf (n,), weight (n,) or (n, channels)); pdf 0 marks a lost sample
    (without a pdf callable, a weight of 0 in every channel);
  eval(wi (n, 3), wo (n, 3)) -> f(wi, wo) |cos wo|, (n,) or (n, channels);
  pdf(wi (n, 3), wo (n, 3)) -> (n,), or None (a sampler whose density is not known in closed form).
Directions z-up, wi the direction given (the camera side in radiance transport); transport 'radiance' or
'importance', masking 'height-correlated' or 'separable', sampling 'vndf' (the visible normals, Heitz 2018) or
'ndf' (normals from D(m) cos, Walter et al. 2007; a dielectric's then refused: ValueError), as a C plugin
declares them. The options are check-bsdf's:
reference 'single-scattering' (the exact BSDF of `bsdf`), 'smith-walk' (the Smith walk's multiple scattering) or
'none' (only the tests against itself); views None (the default grid; anisotropic alpha: views off the axes too)
or a list of THETA or (THETA, PHI) in degrees; stochastic_eval (eval an unbiased noisy estimate: averaged over
repeated calls); samples per view; level (family-wise, Sidak); html a path for the HTML report. Returns the
report as a dict (the JSON of `check-bsdf --json`): "verdict" ("pass" or "fail"), "passed", "tests" (one per
view's sampling and consistency, and the eval check), "eval" (the worst pairs), "bsdf", "alpha", "level".)",
      "sample"_a, "eval"_a, "pdf"_a = py::none(), py::kw_only(), "bsdf"_a, "alpha"_a, "channels"_a = 1,
      "transport"_a = "radiance", "masking"_a = "height-correlated", "sampling"_a = "vndf",
      "samples"_a = 200'000, "seed"_a = 1, "level"_a = 0.01, "arithmetic"_a = "float32", "reference"_a = "single-scattering", "views"_a = py::none(),
      "stochastic_eval"_a = false, "html"_a = py::none());
}

}  // namespace microsim::python
