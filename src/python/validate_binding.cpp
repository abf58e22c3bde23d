// python: validate() on numpy arrays and on the zoo's samplers, the result object, the samplers as
// vectorised functions, and the run of long calls (GIL released, progress, Ctrl-C). See binding.h.
#include "python/binding.h"

#include "measure/validate_all.h"
#include "microfacet/material.h"
#include "microfacet/roughness.h"
#include "stats/binning.h"
#include "stats/histogram_io.h"
#include "validate/bsdf_validation.h"
#include "validate/dump_validation.h"
#include "validate/compare.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <bit>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <filesystem>
#include <mutex>
#include <optional>
#include <thread>

namespace microsim::python {

// ---- long calls --------------------------------------------------------------------------------------------

namespace {

// The latest progress report of a run's workers, handed to the Python thread.
class ProgressRelay {
public:
  void update(std::string_view stage, std::uint64_t done, std::uint64_t total) {
    const std::lock_guard lock(mutex_);
    if (stage_ == stage && done < done_) return;  // reports from several threads arrive out of order
    stage_ = stage;
    done_ = done;
    total_ = total;
    fresh_ = true;
  }
  // Calls progress(stage, done, total) with the latest report, if a new one came (GIL held).
  void forward(const py::object& progress) {
    std::string stage;
    std::uint64_t done = 0, total = 0;
    {
      const std::lock_guard lock(mutex_);
      if (!fresh_) return;
      fresh_ = false;
      stage = stage_;
      done = done_;
      total = total_;
    }
    progress(stage, done, total);
  }

private:
  std::mutex mutex_;
  std::string stage_;
  std::uint64_t done_ = 0, total_ = 0;
  bool fresh_ = false;
};

// The worker thread's end, waited for by the Python thread.
struct Completion {
  std::mutex mutex;
  std::condition_variable done_signal;
  bool done = false;
  std::exception_ptr failure;
  bool wait_for(std::chrono::milliseconds period) {
    std::unique_lock lock(mutex);
    return done_signal.wait_for(lock, period, [this] { return done; });
  }
  void finish(std::exception_ptr e) {
    const std::lock_guard lock(mutex);
    failure = std::move(e);
    done = true;
    done_signal.notify_all();
  }
};

// With the GIL held: forwards the progress and runs the signal handlers; the Python error they raised, if any.
std::optional<py::error_already_set> poll(ProgressRelay& relay, const py::object& progress) {
  try {
    if (!progress.is_none()) relay.forward(progress);
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
  } catch (py::error_already_set& e) {
    return std::move(e);
  }
  return std::nullopt;
}

}  // namespace

void run_interruptible(const std::function<void(const RunControl&)>& work, const py::object& progress,
                       const std::function<py::object()>& partial_result) {
  CancelToken token;
  ProgressRelay relay;
  RunControl run;
  run.cancel = &token;
  run.progress = [&relay](std::string_view stage, std::uint64_t done, std::uint64_t total) {
    relay.update(stage, done, total);
  };
  Completion completion;
  std::optional<py::error_already_set> interruption;
  {
    py::gil_scoped_release release;
    std::thread worker([&] {
      try {
        work(run);
        completion.finish(nullptr);
      } catch (...) {
        completion.finish(std::current_exception());
      }
    });
    while (!completion.wait_for(std::chrono::milliseconds(50))) {
      py::gil_scoped_acquire gil;
      if (interruption) continue;
      interruption = poll(relay, progress);
      if (interruption) token.cancel();
    }
    worker.join();
  }
  if (!interruption) interruption = poll(relay, progress);  // the last report, and a late Ctrl-C
  if (interruption) {
    const py::object partial = partial_result && !completion.failure ? partial_result() : py::none();
    if (!partial.is_none() && interruption->matches(PyExc_KeyboardInterrupt))
      py::setattr(interruption->value(), "partial_result", partial);
    throw *interruption;
  }
  if (completion.failure) std::rethrow_exception(completion.failure);
}

// ---- arguments ---------------------------------------------------------------------------------------------

GGX<double> ggx_of(const py::handle& alpha, const char* what) {
  double ax = 0, ay = 0;
  if (py::isinstance<py::sequence>(alpha) && !py::isinstance<py::str>(alpha)) {
    const auto pair = alpha.cast<std::vector<double>>();
    if (pair.size() != 2) throw py::value_error(std::string(what) + ": give one number or a pair (alpha_x, alpha_y)");
    ax = pair[0];
    ay = pair[1];
  } else {
    ax = ay = alpha.cast<double>();
  }
  check_supported_alpha(what, ax, ay);  // ParseError (std::invalid_argument): ValueError
  return GGX<double>(ax, ay);
}

Vec3<double> view_of(double theta_deg, double phi_deg) {
  if (!(theta_deg >= 0 && theta_deg < 90))
    throw py::value_error("theta must be in [0, 90) degrees, got " + py::repr(py::float_(theta_deg)).cast<std::string>());
  if (!std::isfinite(phi_deg)) throw py::value_error("phi must be finite, got " + py::repr(py::float_(phi_deg)).cast<std::string>());
  return direction_from_degrees(theta_deg, phi_deg);
}

namespace {

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace

py::array checked_array(const py::handle& object, const char* what, int columns, bool exact_float) {
  if (!py::isinstance<py::array>(object) && exact_float)
    throw py::value_error(std::string(what) + ": expected a numpy array, got " + py::repr(py::type::of(object)).cast<std::string>());
  py::array a = py::array::ensure(object);  // the array itself, or a list converted
  if (!a) {
    PyErr_Clear();
    throw py::value_error(std::string(what) + ": expected an array of numbers");
  }
  const char kind = a.dtype().kind();
  const bool float_ok = kind == 'f' && (a.itemsize() == 4 || a.itemsize() == 8);
  if ((exact_float && !float_ok) || (!exact_float && kind != 'f' && kind != 'i' && kind != 'u'))
    throw py::value_error(std::string(what) + ": dtype " + py::str(a.dtype()).cast<std::string>() +
                          " is not supported (expected float32 or float64)");
  const bool shape_ok = columns == 0    ? a.ndim() == 1
                        : columns < 0   ? a.ndim() == 1 || (a.ndim() == 2 && a.shape(1) >= 1)
                                        : a.ndim() == 2 && a.shape(1) == columns;
  if (!shape_ok)
    throw py::value_error(std::string(what) + ": shape " + shape_text(a) + " is not supported (expected " +
                          (columns == 0 ? std::string("(N,)") : columns < 0 ? std::string("(N,) or (N, C)")
                                                                            : "(N, " + std::to_string(columns) + ")") + ")");
  return a;
}

py::object json_object(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

SampleArrayColumn column_of(const py::array& a, int column) {
  const auto* base = static_cast<const char*>(a.data());
  const char order = a.dtype().byteorder();  // '<' little-endian, '>' big-endian, '=' or '|' the machine's
  const bool big_endian = order == '>' || (order != '<' && std::endian::native == std::endian::big);
  return {base + (a.ndim() == 2 ? column * a.strides(1) : 0), a.strides(0), a.itemsize() == 4, big_endian};
}

namespace {

SampleFrame frame_of(const std::string& frame) {
  if (frame == "z-up") return SampleFrame::z_up;
  if (frame == "y-up") return SampleFrame::y_up;
  throw py::value_error("frame: unknown frame '" + frame + "' (valid: z-up, y-up)");
}

// The values (N,) or (N, C) of argument `what`, one row per sample, appended to the reader's columns.
int append_columns(SampleArray& array, const py::handle& values_in, const char* what) {
  const py::array values = checked_array(values_in, what, -1, true);
  if (std::uint64_t(values.shape(0)) != array.rows)
    throw py::value_error(std::string(what) + ": " + std::to_string(values.shape(0)) + " rows for " +
                          std::to_string(array.rows) + " samples (one per sample)");
  const int count = values.ndim() == 1 ? 1 : int(values.shape(1));
  for (int c = 0; c < count; ++c) array.columns.push_back(column_of(values, c));
  return count;
}

// The samples (N, 3), the pdfs (N,) their sampler returned and their weights (N,) or (N, C), read in place
// (whatever their order and strides) as a file's columns x,y,z[,pdf][,weight...] would be.
DirectionSampleReader sample_reader(const py::handle& samples_in, const py::handle& pdfs, const py::handle& weights,
                                    const std::string& frame) {
  const py::array samples = checked_array(samples_in, "samples", 3, true);
  SampleArray array;
  array.rows = std::uint64_t(samples.shape(0));
  for (int c = 0; c < 3; ++c) array.columns.push_back(column_of(samples, c));
  std::string spec = "x,y,z";
  if (!pdfs.is_none()) {
    checked_array(pdfs, "pdfs", 0, true);  // one pdf per sample: (N,)
    append_columns(array, pdfs, "pdfs");
    spec += ",pdf";
  }
  const int channels = weights.is_none() ? 0 : append_columns(array, weights, "weights");
  for (int c = 0; c < channels; ++c) spec += ",weight";
  DirectionSampleReader reader(std::move(array), SampleColumns::parse(spec));
  reader.set_frame(frame_of(frame));
  return reader;
}

// A path (str or os.PathLike) of a sample file rather than an array.
bool is_path(const py::handle& samples) { return py::isinstance<py::str>(samples) || py::hasattr(samples, "__fspath__"); }

// The sample file at `path` (.npy in any order, or text), read as `validate --from` reads it, with its
// `columns` as --columns names them: a file's pdfs and weights are its columns, never arrays beside it.
DirectionSampleReader file_sample_reader(const py::handle& path, const std::optional<std::string>& columns,
                                         const py::handle& pdfs, const py::handle& weights, const std::string& frame) {
  if (!pdfs.is_none() || !weights.is_none())
    throw py::value_error("pdfs and weights are arrays beside an array of samples; a file's are its own columns: "
                          "name them with columns (e.g. columns='x,y,z,pdf,weight')");
  SampleColumns c;
  try {
    if (columns) c = SampleColumns::parse(*columns);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(std::string("columns: ") + e.what());
  }
  DirectionSampleReader reader(py::module_::import("os").attr("fsdecode")(path).cast<std::string>(), c);
  reader.set_frame(frame_of(frame));
  return reader;
}

// The samples' reader: the file of a path, or the array (with the pdfs and weights arrays beside it).
DirectionSampleReader samples_reader(const py::handle& samples, const std::optional<std::string>& columns,
                                     const py::handle& pdfs, const py::handle& weights, const std::string& frame) {
  if (is_path(samples)) return file_sample_reader(samples, columns, pdfs, weights, frame);
  if (columns) throw py::value_error("columns names the columns of a sample file: give samples as a path");
  return sample_reader(samples, pdfs, weights, frame);
}

ValidationOptions validation_options(int rows, double significance, std::uint64_t seed) {
  if (!(significance > 0 && significance < 1))
    throw py::value_error("significance must be in (0, 1), got " + py::repr(py::float_(significance)).cast<std::string>());
  if (rows < 3 || rows > kMaxBinningRows || rows % 2 == 0)
    throw py::value_error("rows must be odd, in [3, " + std::to_string(kMaxBinningRows) + "], got " + std::to_string(rows));
  ValidationOptions o;
  o.rows = rows;
  o.significance = significance;
  o.seed = seed;
  return o;
}

// ---- validate ------------------------------------------------------------------------------------------------

// The BSDF of `validate --bsdf`: a material spec as parse_material reads it, checked as the command line
// checks it against the weights and the claimed density.
std::optional<Material> bsdf_of(const std::optional<std::string>& spec, FilePdf pdf, bool has_weights) {
  if (has_weights && !spec)
    throw py::value_error("weights need bsdf: the weights (f cos / pdf) are tested against the BSDF");
  if (pdf == FilePdf::bsdf && !spec)
    throw py::value_error("pdf='bsdf' is the sampling density of a BSDF: give it with bsdf (e.g. bsdf='dielectric:1.5')");
  if (!spec) return std::nullopt;
  const Material bsdf = parse_material("bsdf", *spec);
  if (!has_weights && pdf != FilePdf::bsdf)
    throw py::value_error("bsdf applies to weights (f cos / pdf) or to pdf='bsdf'");
  if (bsdf.transmits() && pdf != FilePdf::bsdf)
    throw py::value_error("bsdf " + bsdf.describe() + ": a dielectric's samples hold reflections and refractions; test "
                          "them against its sampling density (pdf='bsdf', implied by bsdf)");
  return bsdf;
}

// The claimed density: `pdf`, or with a BSDF its own outgoing density (as `validate --bsdf` implies --pdf bsdf).
FilePdf claimed_pdf_of(const std::optional<std::string>& pdf, const std::optional<std::string>& bsdf,
                       const std::optional<std::string>& against) {
  if (pdf) return parse_file_pdf(*pdf);  // std::invalid_argument naming the valid ones: ValueError
  return bsdf && !against ? FilePdf::bsdf : FilePdf::vndf;
}

// The BSDF's convention: transport mode, masking form and sampled normals (bsdf_convention.h), with a BSDF only;
// the sampled normals set its own density only (pdf 'bsdf', the default with a BSDF).
BsdfConvention convention_of(const std::optional<std::string>& transport, const std::optional<std::string>& masking,
                             const std::optional<std::string>& sampling, const std::optional<std::string>& bsdf,
                             FilePdf claimed) {
  if ((transport || masking) && !bsdf)
    throw py::value_error(std::string(transport ? "transport" : "masking") +
                          " is the convention of a BSDF's weights: give the BSDF with bsdf");
  if (sampling && (!bsdf || claimed != FilePdf::bsdf))
    throw py::value_error("sampling is how a BSDF's sample() draws its normals: it sets the BSDF's own density (bsdf, "
                          "with pdf 'bsdf', its default), not that of another pdf");
  BsdfConvention c;
  if (transport) c.transport = parse_transport_mode("transport", *transport);
  if (masking) c.masking = parse_masking_form("masking", *masking);
  if (sampling) c.normals = parse_sampled_normals("sampling", *sampling);
  return c;
}

// The traced oracle of `validate --against`: "ellipsoid" (traced now, seed mixed as the command line mixes it)
// or a histogram EXR of `trace vndf`.
TracedHistogram oracle_of(const std::string& against, const GGX<double>& ggx, const Vec3<double>& wi, int rows,
                          std::uint64_t rays, std::uint64_t seed, const RunControl& run) {
  if (against != "ellipsoid") return read_histogram_exr(against);
  OracleTraceOptions t;
  t.rays = rays;
  t.seed = oracle_seed(seed);
  t.rows = rows;
  t.run = run;
  TracedHistogram traced = trace_vndf_histogram(ggx, wi, t);
  if (traced.partial) throw Cancelled("while tracing the oracle");
  return traced;
}

// The comparison `against` asks for: the claimed pdf (none), or the traced oracle's two-sample tests.
struct Reference {
  FilePdf claimed = FilePdf::vndf;
  std::optional<Material> bsdf;  // of pdf='bsdf'
  bool above_horizon = false;
  bool lost_as_zero_weight = false;
  std::optional<std::string> against;
  std::uint64_t oracle_rays = 0, seed = 1;
  bool diagnose_frame = true;  // no frame given: a rejection looking like a frame mistake is diagnosed
};

// The samples against the traced oracle, or against what they claim from the view as given (validate_dump_as_given:
// light from inside a dielectric mirrored, as `validate --from` does).
ValidationReport validate_reader(DirectionSampleReader& reader, const GGX<double>& ggx, const Vec3<double>& view,
                                 const ValidationOptions& o, const Reference& r) {
  if (r.against) {
    const TracedHistogram traced = oracle_of(*r.against, ggx, view, o.rows, r.oracle_rays, r.seed, o.run);
    return compare_sample_file_to_trace(reader, "samples", ggx, view, o, traced);
  }
  try {
    return validate_dump_as_given(reader, {r.claimed, r.bsdf, r.above_horizon, r.lost_as_zero_weight}, ggx, view, o,
                                  r.diagnose_frame);
  } catch (const InsufficientData&) {
    throw;
  } catch (const std::invalid_argument& e) {  // the claims' reference (dump_reference)
    throw py::value_error(std::string(r.lost_as_zero_weight ? "lost_as_zero_weight: "
                                      : r.above_horizon     ? "above_horizon: "
                                                            : "") +
                          e.what());
  }
}

// What `against` excludes, as `validate --against` refuses it.
void check_against(const Reference& r, bool has_weights) {
  if (!r.against) return;
  if (r.claimed != FilePdf::vndf) throw py::value_error("against: the traced oracle measures visible normals (pdf='vndf')");
  if (r.above_horizon) throw py::value_error("above_horizon tests against the analytic pdf, not against the traced oracle");
  if (r.lost_as_zero_weight) throw py::value_error("lost_as_zero_weight applies to weights, not against the traced oracle");
  if (has_weights) throw py::value_error("weights are tested against the analytic BSDF, not against the traced oracle");
  if (*r.against != "ellipsoid" && std::filesystem::path(*r.against).extension() != ".exr")
    throw py::value_error("against '" + *r.against + "': use 'ellipsoid' or a histogram .exr from `microsim trace vndf`");
}

// What validate() is asked beside the arrays and the view (keyword arguments).
struct DumpArguments {
  std::optional<std::string> pdf, bsdf, transport, masking, sampling, columns, frame;
  int rows = 31;
  double significance = 0.01;
  bool above_horizon = false;
  std::optional<std::uint64_t> dropped;
  bool lost_as_zero_weight = false;
  std::optional<std::string> against;
  std::uint64_t oracle_rays = 0, seed = 1;
};

ValidationReport validate_array(const py::handle& samples, const py::handle& alpha, double theta, double phi,
                                const py::handle& weights, const py::handle& pdfs, const DumpArguments& d,
                                const py::object& progress) {
  const GGX<double> ggx = ggx_of(alpha);
  // Light from inside a dielectric: theta in (90, 180], validated as its mirror image (dump_validation.h).
  const bool inside = theta > 90 && theta <= 180 && d.bsdf && !d.against;
  const Vec3<double> view = inside ? direction_from_degrees(theta, phi) : view_of(theta, phi);
  ValidationOptions o = validation_options(d.rows, d.significance, d.seed);
  if (d.dropped && !d.above_horizon) throw py::value_error("dropped applies with above_horizon=True only");
  o.dropped_below_horizon = d.dropped;
  const FilePdf claimed = claimed_pdf_of(d.pdf, d.bsdf, d.against);
  DirectionSampleReader reader = samples_reader(samples, d.columns, pdfs, weights, d.frame.value_or("z-up"));
  const bool has_weights = reader.columns().channels() > 0;
  const std::optional<Material> material = bsdf_of(d.bsdf, claimed, has_weights);
  try {
    (void)seen_from_outside(view, material);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(std::string("theta: ") + e.what());
  }
  if (has_weights) o.bsdf = material;  // the weight test
  o.convention = convention_of(d.transport, d.masking, d.sampling, d.bsdf, claimed);
  if (has_weights && material)
    if (const std::string why = untested_weights_reason(*material, o.convention); !why.empty())
      throw py::value_error("sampling='ndf' with weights: " + why);
  if (d.above_horizon && !claims_reflected_directions(claimed))
    throw py::value_error("above_horizon applies to reflected directions: give pdf='reflection', 'bounded' or 'bsdf'");
  if (d.lost_as_zero_weight && (d.above_horizon || !has_weights))
    throw py::value_error("lost_as_zero_weight needs weights (the lost samples' rows weigh 0) and excludes above_horizon "
                          "(the lost samples are dropped or kept, not both)");
  const Reference reference{claimed, material, d.above_horizon, d.lost_as_zero_weight, d.against, d.oracle_rays, d.seed,
                            !d.frame};
  check_against(reference, has_weights);
  ValidationReport report;
  run_interruptible(
      [&](const RunControl& run) {
        o.run = run;
        report = validate_reader(reader, ggx, view, o, reference);
      },
      progress);
  report.sampler = "samples";
  report.wi = view;
  return report;
}

// validate()'s signature: the arrays, the view and its keyword arguments.
ValidationReport validate_with_keywords(const py::handle& samples, const py::handle& alpha, double theta, double phi,
                                        std::optional<std::string> pdf, const py::handle& weights, const py::handle& pdfs,
                                        std::optional<std::string> bsdf, std::optional<std::string> transport,
                                        std::optional<std::string> masking, std::optional<std::string> sampling,
                                        std::optional<std::string> columns,
                                        std::optional<std::string> frame, int rows,
                                        double significance, bool above_horizon, std::optional<std::int64_t> dropped,
                                        bool lost_as_zero_weight, std::optional<std::string> against,
                                        std::uint64_t oracle_rays, std::uint64_t seed, const py::object& progress) {
  if (dropped && *dropped < 0)
    throw py::value_error("dropped must be a count of samples (>= 0), got " + std::to_string(*dropped));
  const std::optional<std::uint64_t> count = dropped ? std::optional<std::uint64_t>(std::uint64_t(*dropped)) : std::nullopt;
  const DumpArguments d{pdf,           bsdf,          transport, masking, sampling, columns,     frame, rows,
                        significance,  above_horizon, count,     lost_as_zero_weight, against,  oracle_rays, seed};
  return validate_array(samples, alpha, theta, phi, weights, pdfs, d, progress);
}

ValidationReport validate_zoo_sampler(const std::string& name, const py::handle& alpha, double theta, double phi,
                                      std::uint64_t samples, std::uint64_t seed, const std::string& precision, int rows,
                                      double significance, const py::object& progress) {
  const SamplerInfo* sampler = find_sampler(name);
  if (!sampler) throw py::value_error("sampler: unknown sampler '" + name + "' (valid: " + py::str(py::cast(sampler_names())).cast<std::string>() + ")");
  const GGX<double> ggx = ggx_of(alpha);
  const Vec3<double> wi = view_of(theta, phi);
  ValidationOptions o = validation_options(rows, significance, seed);
  if (precision != "double" && precision != "float") throw py::value_error("precision: 'double' or 'float', got '" + precision + "'");
  o.precision = precision == "float" ? Precision::float32 : Precision::float64;
  o.samples = samples;
  require_samples_for_any_test(samples);
  ValidationReport report;
  run_interruptible([&](const RunControl& run) {
    o.run = run;
    report = validate_sampler(*sampler, ggx, wi, o);
  }, progress);
  return report;
}

// ---- the result ---------------------------------------------------------------------------------------------

// p-values by test: the chi-square tests ("chi2_sphere", "chi2_lobe") and the applicable statistical checks.
py::dict p_values_of(const ValidationReport& r) {
  py::dict out;
  for (const BinnedTest& b : r.binned) out[py::str(b.name)] = b.chi2.p_value;
  for (const SubTest& c : r.checks)
    if (c.applicable && c.statistical) out[py::str(c.name)] = c.p_value;
  return out;
}

py::list worst_cells_of(const ValidationReport& r) {
  py::list out;
  for (const BinnedTest& b : r.binned)
    for (const CellReport& c : b.chi2.worst_cells)
      out.append(py::dict(py::arg("binning") = b.binning, py::arg("bin") = c.bin, py::arg("observed") = c.observed,
                          py::arg("expected") = c.expected, py::arg("contribution") = c.contribution,
                          py::arg("location") = c.location));
  return out;
}

std::string repr_of(const ValidationReport& r) {
  return std::string("<ValidationResult ") + (r.passed ? "PASS" : "REJECTED") + " p=" +
         py::repr(py::float_(r.p_value)).cast<std::string>() + " samples=" + std::to_string(r.samples) +
         (r.failures.empty() ? "" : " failure: " + r.failures.front()) +
         (r.hints.empty() ? "" : " hint: " + r.hints.front()) + ">";
}

void bind_result(py::module_& m) {
  py::class_<ValidationReport>(m, "ValidationResult", "The report of one validation (what `microsim validate --json` writes).")
      .def_property_readonly("passed", [](const ValidationReport& r) { return r.passed; }, "True when every test passed")
      .def_property_readonly("verdict", [](const ValidationReport& r) { return r.passed ? "pass" : "fail"; }, "'pass' or 'fail'")
      .def_readonly("p_value", &ValidationReport::p_value, "Sidak-adjusted smallest p-value of the statistical tests")
      .def_readonly("statistic", &ValidationReport::statistic, "chi-square statistic of the test with the smallest p")
      .def_readonly("dof", &ValidationReport::dof, "its degrees of freedom")
      .def_readonly("samples", &ValidationReport::samples, "number of samples tested")
      .def_readonly("failures", &ValidationReport::failures, "why it failed (empty when passed)")
      .def_readonly("hints", &ValidationReport::hints,
                    "what would explain a rejection: a frame mistake, samples a renderer dropped (as the CLI prints)")
      .def_readonly("notes", &ValidationReport::notes,
                    "what the report says whatever the verdict: what the dump could not show, the weights' convention")
      .def_readonly("seconds", &ValidationReport::seconds, "wall-clock time of the validation")
      .def_property_readonly("p_values", &p_values_of, "p-value of each statistical test, by name")
      .def_property_readonly("worst_cells", &worst_cells_of, "the cells contributing most to each chi-square statistic")
      .def("to_dict", [](const ValidationReport& r) { return json_object(to_json(r)); },
           "The report as a dict: the JSON of `microsim validate --json`")
      .def("__bool__", [](const ValidationReport& r) { return r.passed; })
      .def("__repr__", &repr_of);
}

// ---- samplers --------------------------------------------------------------------------------------------------

using Rows = py::array_t<double, py::array::c_style | py::array::forcecast>;

// Row i of the samples: the sampler (its float or double version) at wi (row i, or the single row) and u row i;
// NaN where it returns nothing.
template <class T>
void draw_rows(SampleResult<T> (*sample)(const GGX<T>&, const Vec3<T>&, Vec2<T>), const GGX<double>& ggx,
               const Rows& wi, const Rows& u, double* directions, double* pdfs) {
  const GGX<T> g(T(ggx.alpha_x()), T(ggx.alpha_y()));
  for (py::ssize_t i = 0; i < u.shape(0); ++i) {
    const double* w = wi.data(wi.shape(0) == 1 ? 0 : i, 0);
    const double* ui = u.data(i, 0);
    const auto s = sample(g, Vec3<T>(T(w[0]), T(w[1]), T(w[2])), Vec2<T>(T(ui[0]), T(ui[1])));
    for (int c = 0; c < 3; ++c) directions[3 * i + c] = s ? double(s->direction[c]) : std::nan("");
    pdfs[i] = s ? double(s->pdf) : std::nan("");
  }
}

// Samples of `name` for each row of u (N, 2): (directions (N, 3), pdfs (N,)).
py::tuple sample_vectorised(const std::string& name, const py::handle& wi_in, const py::handle& alpha, const py::handle& u_in,
                            const std::string& precision) {
  const SamplerInfo* sampler = find_sampler(name);
  if (!sampler) throw py::value_error("unknown sampler '" + name + "' (valid: " + py::str(py::cast(sampler_names())).cast<std::string>() + ")");
  if (precision != "double" && precision != "float") throw py::value_error("precision: 'double' or 'float', got '" + precision + "'");
  const GGX<double> ggx = ggx_of(alpha);
  const Rows wi = directions_of(wi_in, "wi");
  const Rows u = Rows::ensure(checked_array(u_in, "u", 2, false));
  const py::ssize_t n = u.shape(0);
  if (wi.shape(0) != 1 && wi.shape(0) != n) throw py::value_error("wi: one direction, or one per row of u");
  py::array_t<double> directions({n, py::ssize_t(3)});
  py::array_t<double> pdfs(n);
  double *d = directions.mutable_data(), *p = pdfs.mutable_data();
  {
    py::gil_scoped_release release;
    if (precision == "float") draw_rows(sampler->sample_float, ggx, wi, u, d, p);
    else draw_rows(sampler->sample_double, ggx, wi, u, d, p);
  }
  return py::make_tuple(directions, pdfs);
}

}  // namespace

py::array_t<double, py::array::c_style | py::array::forcecast> directions_of(const py::handle& array, const char* what) {
  py::array a = py::array::ensure(array);
  if (!a) throw py::value_error(std::string(what) + ": expected an array of directions (N, 3) or (3,)");
  if (a.ndim() == 1 && a.shape(0) == 3) a = a.attr("reshape")(1, 3);
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(checked_array(a, what, 3, false));
}

// `validate --all`: the zoo over its grid, then the BSDF samplers over theirs, and the batch's verdict; the
// run built as the command line builds it (validation_run in apps/cmd_validate.cpp).
py::object validate_all_with_keywords(std::uint64_t samples, std::uint64_t seed, const std::string& precision, int rows,
                                      double significance, int threads, const py::object& progress) {
  ValidationRun run;
  run.batch = true;
  run.seed = seed;
  run.family_significance = significance;
  run.options = validation_options(rows, significance, seed);
  if (precision != "double" && precision != "float") throw py::value_error("precision: 'double' or 'float', got '" + precision + "'");
  run.options.precision = precision == "float" ? Precision::float32 : Precision::float64;
  run.options.samples = samples;
  run.cases = zoo_cases(seed);
  run.options.significance = sidak_significance(significance, int(run.cases.size()));
  require_samples_for_any_test(samples);
  if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores), got " + std::to_string(threads));
  std::optional<ZooResult> result;
  auto to_python = [](const ZooResult& r) {
    py::object out = json_object(to_json(r));
    out["exit_code"] = exit_code(r);
    return out;
  };
  run_interruptible([&](const RunControl& control) {
    ValidationRun r = run;
    r.options.run = control;
    r.options.run.threads = threads;
    result = validate_all(r);
  }, progress, [&] { return result ? to_python(*result) : py::object(py::none()); });
  return to_python(*result);
}

void bind_validation(py::module_& m) {
  using namespace pybind11::literals;
  bind_result(m);
  m.def("validate", &validate_with_keywords, R"(Validates samples against the density they claim (what `microsim validate --from` does).

samples: (N, 3) float32 or float64 array of unit directions in the z-up frame (any order or strides: read in
  place); NaN rows are the sampler's failures (the validation rejects and names them). Or the path (str or
  os.PathLike) of a sample file (.npy in C or Fortran order, or text) as `validate --from FILE` reads it.
alpha: roughness, a number or (alpha_x, alpha_y); theta, phi: the view in degrees (theta in [0, 90); with a
  dielectric bsdf also (90, 180]: light from inside, validated as its mirror image).
pdf: the claimed density: 'vndf' (normals, D_v; the default without bsdf), 'ndf' (normals, D(m) m.z),
  'bounded' or 'reflection' (reflected directions), 'bsdf' (the outgoing directions of `bsdf`'s VNDF
  sampling, a conductor's reflections, a dielectric's reflections and refractions; the default with bsdf).
weights: optional (N,) or (N, C) array of the weights f cos / pdf the sampler returned (one column per
  channel), tested against `bsdf` ('mirror', 'conductor:ETA,K[;ETA,K...]', 'dielectric:ETA' as a
  material spec of `validate --bsdf`).
pdfs: optional (N,) array of the pdfs the sampler returned, checked against the claimed pdf.
transport: the weights' transport mode with bsdf: 'radiance' (default: camera paths, a refraction's weight holds
  (n_given / n_sampled)^2) or 'importance' (light paths); masking: 'height-correlated' (default, Smith's G2)
  or 'separable' (G1(wi) G1(wo), as Mitsuba 3); sampling: the normals the BSDF's sample() draws, which set the
  density of its directions: 'vndf' (default: the visible normals) or 'ndf' (D(m) cos, Walter et al. 2007, as
  Mitsuba 3 with sample_visible=False).
columns: a file's columns as `--columns` names them ('x,y,z' by default; 'x,y,z,pdf,weight', '-' to skip a
  column): with a path, its pdfs and weights are its columns (the arrays pdfs and weights are for arrays).
frame: 'z-up' (default) or 'y-up'; without it a rejection that looks like a frame mistake is diagnosed (hints);
rows, significance: as the command line's --rows, --significance;
above_horizon, dropped: reflections above the horizon only (--above-horizon, --dropped).
lost_as_zero_weight: the samples the sampler lost are rows of weight 0, as Mitsuba 3's sample() returns them
  (--lost-as-zero-weight); they count as its failures.
against: None (the claimed pdf), 'ellipsoid' (the oracle traced now with oracle_rays rays, its seed mixed from
  `seed` as the command line does) or the path of a histogram EXR of `microsim trace vndf`: the two-sample
  chi-square test against the traced oracle (`validate --against`).
progress: optional callable progress(stage, done, total).
Returns a ValidationResult; raises ValueError for bad input (the command line's messages) and
KeyboardInterrupt on Ctrl-C.)",
        "samples"_a, "alpha"_a, "theta"_a, "phi"_a = 0.0, "pdf"_a = py::none(), "weights"_a = py::none(),
        "pdfs"_a = py::none(), py::kw_only(), "bsdf"_a = py::none(), "transport"_a = py::none(), "masking"_a = py::none(),
        "sampling"_a = py::none(), "columns"_a = py::none(), "frame"_a = py::none(), "rows"_a = 31, "significance"_a = 0.01,
        "above_horizon"_a = false, "dropped"_a = py::none(), "lost_as_zero_weight"_a = false,
        "against"_a = py::none(), "oracle_rays"_a = 4'000'000, "seed"_a = 1, "progress"_a = py::none());
  m.def("validate_sampler", &validate_zoo_sampler, R"(Validates a sampler of the zoo (what `microsim validate --sampler` does).

name: a name of sampler_names(); alpha, theta, phi as for validate(); samples: how many to draw;
seed: sample i uses CounterRng(seed, i), as the command line; precision: 'double' or 'float' (--float).
Returns a ValidationResult identical to the command line's for the same arguments.)",
        "name"_a, "alpha"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "samples"_a = 1'000'000, "seed"_a = 1,
        "precision"_a = "double", "rows"_a = 31, "significance"_a = 0.01, "progress"_a = py::none());
  m.def("sample", &sample_vectorised, R"(Draws with a sampler of the zoo, vectorised.

name: a name of sampler_names(); wi: the view, (3,) or (N, 3); alpha: a number or (alpha_x, alpha_y);
u: (N, 2) uniforms in [0, 1); precision: 'double' or 'float' (the sampler's float version, as --float).
Returns (directions (N, 3), pdfs (N,)), float64; rows where the sampler returns nothing are NaN.)",
        "name"_a, "wi"_a, "alpha"_a, "u"_a, "precision"_a = "double");
  m.def("sampler_names", &sampler_names, "The names of the samplers of the zoo.");
  m.def("validate_all", &validate_all_with_keywords, R"(Validates the whole zoo over the standard grid (what `microsim validate --all` does).

samples: per validation (the command line's default 200000); seed, precision ('double' or 'float', as
--float), rows, significance (the family-wise level over the batch, Sidak) as the command line's options;
threads: 0 for all cores; progress: optional callable progress(stage, done, total).
Returns the dict `validate --all --json` writes: "verdict" ('pass', 'fail'), "summary" (a row per sampler:
passed, total, min and max p-value, expectation_met), "results" (a row per validation with its p-value and
passed), the run's parameters, and "exit_code" (the command line's: 0 pass, 1 fail). KeyboardInterrupt on
Ctrl-C carries the validations done as `partial_result`.)",
        py::kw_only(), "samples"_a = 200'000, "seed"_a = 1, "precision"_a = "double", "rows"_a = 31,
        "significance"_a = 0.01, "threads"_a = 0, "progress"_a = py::none());
}

}  // namespace microsim::python
