// python: the `microsim` module: exception translation, the analytic GGX functions on arrays, the traced
// VNDF oracle with its bin geometry, heightfield surfaces (building, loading, tracing, masking) and the
// scattering models (see binding.h, docs/guide/python.md).
#include "python/binding.h"

#include "core/errors.h"
#include "measure/masking.h"
#include "measure/scatter.h"
#include "measure/vndf.h"
#include "microfacet/beckmann.h"
#include "microfacet/bsdf.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "scatter/analytic_scatter.h"
#include "scatter/scatter_setup.h"
#include "scatter/smith_walk.h"
#include "scatter/surface_scatter.h"
#include "stats/binning.h"
#include "stats/scatter_io.h"

#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <complex>
#include <optional>
#include <string>

namespace microsim::python {
namespace {

using namespace pybind11::literals;

// ---- errors -------------------------------------------------------------------------------------------------
// As the command line maps them to exit codes (core/errors.h): bad input (exit 2) -> ValueError, an internal
// failure (exit 3) -> RuntimeError, a cancelled step without partial result (130) -> KeyboardInterrupt.
void translate_errors(std::exception_ptr error) {
  try {
    std::rethrow_exception(error);
  } catch (const InternalError& e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
  } catch (const Cancelled& e) {
    PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
  } catch (const py::builtin_exception&) {
    throw;  // pybind11's own (value_error, ...): its translator
  } catch (const std::invalid_argument& e) {
    PyErr_SetString(PyExc_ValueError, e.what());
  } catch (const std::runtime_error& e) {  // a file that cannot be read, a malformed one
    PyErr_SetString(PyExc_ValueError, e.what());
  }
}

// ---- the analytic functions on arrays ---------------------------------------------------------------------------

using Directions = py::array_t<double, py::array::c_style | py::array::forcecast>;

Vec3<double> row(const Directions& a, py::ssize_t i) {
  const py::ssize_t k = a.shape(0) == 1 ? 0 : i;
  const double* p = a.data(k, 0);
  return {p[0], p[1], p[2]};
}

// f(ggx, w) for each row of w.
template <class F> py::array_t<double> per_direction(const py::handle& w_in, const py::handle& alpha, F f) {
  const GGX<double> ggx = ggx_of(alpha);
  const Directions w = directions_of(w_in, "w");
  py::array_t<double> out(w.shape(0));
  double* o = out.mutable_data();
  for (py::ssize_t i = 0; i < w.shape(0); ++i) o[i] = f(ggx, row(w, i));
  return out;
}

// f(ggx, a, b) for each pair of rows of a and b; a single row of either is paired with every row of the other.
template <class F>
py::array_t<double> per_pair(const py::handle& a_in, const py::handle& b_in, const py::handle& alpha, F f) {
  const GGX<double> ggx = ggx_of(alpha);
  const Directions a = directions_of(a_in, "first direction"), b = directions_of(b_in, "second direction");
  const py::ssize_t n = std::max(a.shape(0), b.shape(0));
  if ((a.shape(0) != 1 && a.shape(0) != n) || (b.shape(0) != 1 && b.shape(0) != n))
    throw py::value_error("directions: " + std::to_string(a.shape(0)) + " and " + std::to_string(b.shape(0)) +
                          " rows (give the same number, or one row for all)");
  py::array_t<double> out(n);
  double* o = out.mutable_data();
  for (py::ssize_t i = 0; i < n; ++i) o[i] = f(ggx, row(a, i), row(b, i));
  return out;
}

void bind_analytic(py::module_& m) {
  using namespace pybind11::literals;
  using G = GGX<double>;
  using V = Vec3<double>;
  // Walter et al. 2007 eq. 33; Heitz 2014 (JCGT 3(2)) eq. 86, 99, 16: the formulas are in microfacet/ggx.h.
  m.def("D", [](py::handle m_, py::handle a) { return per_direction(m_, a, [](const G& g, const V& v) { return g.D(v); }); },
        "GGX normal distribution D(m) (Walter et al. 2007, eq. 33) of normals m (N, 3).", "m"_a, "alpha"_a);
  m.def("Lambda", [](py::handle w, py::handle a) { return per_direction(w, a, [](const G& g, const V& v) { return g.Lambda(v); }); },
        "Smith Lambda(w) (Heitz 2014, eq. 86) of directions w (N, 3).", "w"_a, "alpha"_a);
  m.def("G1", [](py::handle w, py::handle a) { return per_direction(w, a, [](const G& g, const V& v) { return g.G1(v); }); },
        "Smith masking G1(w) = 1 / (1 + Lambda(w)) of directions w (N, 3).", "w"_a, "alpha"_a);
  m.def("G2", [](py::handle wi, py::handle wo, py::handle a) {
          return per_pair(wi, wo, a, [](const G& g, const V& x, const V& y) { return g.G2(x, y); });
        }, "Height-correlated masking-shadowing G2(wi, wo) (Heitz 2014, eq. 99).", "wi"_a, "wo"_a, "alpha"_a);
  m.def("D_v", [](py::handle wi, py::handle m_, py::handle a) {
          return per_pair(wi, m_, a, [](const G& g, const V& x, const V& y) { return g.visible_normal_pdf(x, y); });
        }, "Visible normal distribution D_v(wi, m) = G1(wi) <wi, m>+ D(m) / wi.z (Heitz 2014, eq. 16), per unit solid angle of m.",
        "wi"_a, "m"_a, "alpha"_a);
  m.def("reflection_pdf", [](py::handle wi, py::handle wo, py::handle a) {
          return per_pair(wi, wo, a, [](const G& g, const V& x, const V& y) { return g.visible_reflection_pdf(x, y); });
        }, "pdf of the reflected direction wo under VNDF sampling, D_v(wi, m) / (4 <wi, m>).", "wi"_a, "wo"_a, "alpha"_a);
  m.def("mirror_brdf", [](py::handle wi, py::handle wo, py::handle a) {
          return per_pair(wi, wo, a, [](const G& g, const V& x, const V& y) { return mirror_brdf(g, x, y); });
        }, "Microfacet BRDF of perfect-mirror facets, D G2 / (4 |wi.z| |wo.z|) (microfacet/bsdf.h).", "wi"_a, "wo"_a, "alpha"_a);
  m.def("conductor_brdf", [](py::handle wi, py::handle wo, py::handle a, std::complex<double> eta) {
          return per_pair(wi, wo, a, [eta](const G& g, const V& x, const V& y) { return conductor_brdf(g, eta, x, y); });
        }, "Microfacet BRDF of conductor facets with complex index eta (Fresnel of a conductor).", "wi"_a, "wo"_a, "alpha"_a, "eta"_a);
  m.def("dielectric_bsdf", [](py::handle wi, py::handle wo, py::handle a, double eta) {
          return per_pair(wi, wo, a, [eta](const G& g, const V& x, const V& y) { return dielectric_bsdf(g, eta, x, y); });
        }, "Rough dielectric BSDF (Walter et al. 2007, eq. 20-21) with relative index eta; wo on either side.",
        "wi"_a, "wo"_a, "alpha"_a, "eta"_a);
}

// ---- the traced VNDF oracle -----------------------------------------------------------------------------------

// The geometry of a binning's bins as numpy arrays (bin = row * cols + col, reshaped (rows, cols)): the bin
// centres as directions, their parameter-space angles, and each bin's solid angle (the cubature of 1).
py::dict bin_geometry(const DirectionBinning& b) {
  const py::ssize_t rows = b.rows(), cols = b.cols();
  py::array_t<double> centres({rows, cols, py::ssize_t(3)}), theta({rows, cols}), phi({rows, cols});
  for (int k = 0; k < b.size(); ++k) {
    const double t = b.center_theta_deg(k) * kPi<double> / 180, p = b.center_phi_deg(k) * kPi<double> / 180;
    const Vec3<double> w = b.from_param(spherical_direction(t, p));
    for (int c = 0; c < 3; ++c) centres.mutable_data()[3 * k + c] = w[c];
    theta.mutable_data()[k] = b.center_theta_deg(k);
    phi.mutable_data()[k] = b.center_phi_deg(k);
  }
  const std::vector<double> solid = b.integrate([](const Vec3<double>&) { return 1.0; });
  return py::dict("name"_a = b.name(), "centres"_a = centres, "param_theta_deg"_a = theta, "param_phi_deg"_a = phi,
                  "solid_angle"_a = py::array_t<double>({rows, cols}, solid.data()));
}

// One binning's histogram: its geometry, counts and analytic bin probabilities (when known).
py::dict binning_dict(const DirectionBinning& b, const std::vector<std::uint64_t>& counts,
                      const std::vector<double>& probability) {
  const py::ssize_t rows = b.rows(), cols = b.cols();
  py::dict d = bin_geometry(b);
  d["counts"] = py::array_t<std::uint64_t>({rows, cols}, counts.data());
  if (!probability.empty()) d["expected_probability"] = py::array_t<double>({rows, cols}, probability.data());
  return d;
}

py::dict histogram_dict(const TracedHistogram& h) {
  py::dict bins;
  for (std::size_t i = 0; i < h.binnings.size(); ++i)
    bins[py::str(h.binnings[i].name())] =
        binning_dict(h.binnings[i], h.counts[i], i < h.probability.size() ? h.probability[i] : std::vector<double>{});
  return py::dict("rays"_a = h.rays, "hits"_a = h.hits, "partial"_a = h.partial, "attributes"_a = h.attributes,
                  "binnings"_a = bins);
}

// The request of `trace vndf` (ellipsoid or heightfield), its view and count checked as the command does.
VndfRequest vndf_request(double theta, double phi, std::uint64_t rays, std::uint64_t seed, int rows) {
  view_of(theta, phi);  // the checks of `trace vndf --theta/--phi`
  if (rays < 1) throw py::value_error("rays must be at least 1");
  VndfRequest request;
  request.theta_deg = theta;
  request.phi_deg = phi;
  request.rays = rays;
  request.seed = seed;
  request.rows = rows;
  return request;
}

py::dict trace_vndf(const py::handle& alpha, double theta, double phi, std::uint64_t rays, std::uint64_t seed, int rows,
                    int mesh_level, int threads, const py::object& progress) {
  const GGX<double> ggx = ggx_of(alpha);
  VndfRequest request = vndf_request(theta, phi, rays, seed, rows);
  if (mesh_level < -1 || mesh_level > 9) throw py::value_error("mesh_level must be -1 (the exact quadric) or 0..9");
  std::optional<EllipsoidVndf> result;
  run_interruptible(
      [&](const RunControl& run) {
        request.run = run;
        request.run.threads = threads;
        const EllipsoidTarget target(ggx.alpha_x(), ggx.alpha_y(), mesh_level);
        result = measure_ellipsoid_vndf(target, request);
      },
      progress, [&]() -> py::object { return result ? py::object(histogram_dict(result->histogram)) : py::none(); });
  return histogram_dict(result->histogram);
}

// `trace vndf --surface`: a heightfield's VNDF, in the same bins, against Smith's prediction.
py::dict trace_surface_vndf(const microgeom::Heightfield& surface, double theta, double phi, std::uint64_t rays,
                            std::uint64_t seed, int rows, int threads, const py::object& progress) {
  VndfRequest request = vndf_request(theta, phi, rays, seed, rows);
  std::optional<HeightfieldVndf> result;
  run_interruptible(
      [&](const RunControl& run) {
        request.run = run;
        request.run.threads = threads;
        result = measure_heightfield_vndf(surface, "numpy heightfield", request);
      },
      progress, [&]() -> py::object { return result ? py::object(histogram_dict(result->histogram)) : py::none(); });
  return histogram_dict(result->histogram);
}

// ---- masking ---------------------------------------------------------------------------------------------------

MaskingRequest masking_request(double theta, double phi, std::optional<double> theta_l, double phi_l, double cone,
                               std::uint64_t samples, std::uint64_t seed, int bins, double grazing_share) {
  view_of(theta, phi);  // `trace masking --theta/--phi`
  if (theta_l) view_of(*theta_l, phi_l);
  if (!(cone > 0 && cone <= 90)) throw py::value_error("cone must be in (0, 90] degrees");
  if (samples < 1) throw py::value_error("samples must be at least 1");
  MaskingRequest r;
  r.theta_deg = theta;
  r.phi_deg = phi;
  r.theta_l_deg = theta_l;
  r.phi_l_deg = phi_l;
  r.cone_deg = cone;
  r.samples = samples;
  r.seed = seed;
  r.bins = bins;
  r.grazing_share = grazing_share;
  return r;
}

// `trace masking --surface`: G1 (and G2 with a light) measured on the heightfield, beside Smith's; the dict of
// the command line's JSON "masking" object.
py::object masking(const microgeom::Heightfield& surface, double theta, double phi, std::uint64_t samples,
                   std::uint64_t seed, int bins, std::optional<double> theta_l, double phi_l, double cone,
                   double grazing_share, const std::string& geometry, int threads, const py::object& progress) {
  MaskingRequest request = masking_request(theta, phi, theta_l, phi_l, cone, samples, seed, bins, grazing_share);
  const HeightfieldGeometry g = heightfield_geometry_from_string(geometry);
  std::optional<SurfaceMasking> result;
  run_interruptible(
      [&](const RunControl& run) {
        request.run = run;
        request.run.threads = threads;
        const MaskingSurface scene(surface, "numpy heightfield", g, /*trace=*/true);
        result = measure_masking(scene, request);
      },
      progress, [&]() -> py::object { return result ? json_object(to_json(result->result)) : py::none(); });
  return json_object(to_json(result->result));
}

py::dict read_histogram_file(const std::string& path) { return histogram_dict(read_histogram_exr(path)); }

// ---- scattering ------------------------------------------------------------------------------------------------

// A scattering result: the summary of `scatter --json` (albedos per order with their errors, unfinished, lost),
// and per channel and order bin (1, 2, 3, 4, 5+) the mean weight per launched path leaving into each bin and its
// standard error, (channels, 5, rows, cols), over the hemispheres binning's geometry.
py::dict scatter_dict(const ScatterHistogram& h, int rows_per_hemisphere) {
  const DirectionBinning b = DirectionBinning::hemispheres(rows_per_hemisphere);
  const std::vector<py::ssize_t> shape{h.channels(), kScatterOrderBins, b.rows(), b.cols()};
  py::array_t<double> mean(shape), error(shape);
  double *m = mean.mutable_data(), *e = error.mutable_data();
  for (int c = 0; c < h.channels(); ++c)
    for (int o = 0; o < kScatterOrderBins; ++o)
      for (std::size_t k = 0; k < h.bins(); ++k, ++m, ++e) {
        const Estimate x = mean_per_path(h.histogram(c, o).weight(k), h.histogram(c, o).weight_squared(k), h.paths());
        *m = x.value;
        *e = x.standard_error;
      }
  return py::dict("summary"_a = json_object(scatter_summary_json(h)), "paths"_a = h.paths(), "partial"_a = h.partial,
                  "mean_weight"_a = mean, "stderr"_a = error, "binning"_a = bin_geometry(b));
}

ScatterOptions scatter_options(double theta, double phi, const std::string& material, std::uint64_t rays,
                               std::uint64_t seed, int max_order, int rows) {
  if (!std::isfinite(theta) || theta < 0 || theta > 180 || theta == 90)
    throw py::value_error("theta must be in [0, 90) (from above) or (90, 180] (from below), got " + std::to_string(theta));
  if (!std::isfinite(phi)) throw py::value_error("phi must be finite");
  ScatterOptions o;
  o.wi = spherical_direction(theta * kPi<double> / 180, phi * kPi<double> / 180);
  o.material = parse_material("material", material);
  if (o.wi.z() < 0 && !o.material.transmits())
    throw py::value_error("theta " + std::to_string(theta) + ": light from below needs a dielectric (material " +
                          o.material.describe() + " is opaque)");
  o.paths = rays;
  o.seed = seed;
  o.max_order = max_order;
  o.rows = rows;
  check_scatter_options(o);
  return o;
}

// Runs a sampled scattering model, its partial histogram kept on Ctrl-C.
py::dict run_scatter(const std::function<ScatterHistogram(const ScatterOptions&)>& model, ScatterOptions o, int threads,
                     const py::object& progress) {
  std::optional<ScatterHistogram> result;
  run_interruptible(
      [&](const RunControl& run) {
        o.run = run;
        o.run.threads = threads;
        result = model(o);
      },
      progress, [&]() -> py::object { return result ? py::object(scatter_dict(*result, o.rows)) : py::none(); });
  return scatter_dict(*result, o.rows);
}

// `scatter --model smith-walk`: the Smith random walk (Heitz et al. 2016, "Multiple-Scattering Microfacet BSDFs
// with the Smith Model", SIGGRAPH).
py::dict smith_walk(const py::handle& alpha, double theta, double phi, const std::string& material, const std::string& ndf,
                    const std::string& heights, const std::string& walk_kernel, std::uint64_t rays, std::uint64_t seed,
                    int max_order, int rows, int threads, const py::object& progress) {
  SmithMicrosurface surface;
  const GGX<double> ggx = ggx_of(alpha);
  surface.alpha_x = ggx.alpha_x();
  surface.alpha_y = ggx.alpha_y();
  surface.ndf = parse_ndf_kind("ndf", ndf);
  surface.heights = parse_height_distribution("heights", heights);
  check_smith_microsurface(surface);
  const ScatterOptions o = scatter_options(theta, phi, material, rays, seed, max_order, rows);
  const WalkKernel kernel = parse_walk_kernel("walk_kernel", walk_kernel);
  if (kernel == WalkKernel::lanes && !smith_walk_lanes_support(surface, o))  // refused before any work
    throw py::value_error("walk_kernel 'lanes': " + describe(surface) + " with " + o.material.describe() +
                          " is not supported (GGX, uniform heights, a mirror, a conductor or a dielectric)");
  return run_scatter(smith_walk_paths(surface, kernel), o, threads, progress);
}

// `scatter --model analytic`: the single-scattering BSDF binned by cubature (the exact expectation of order 1),
// per channel and bin (channels, rows, cols), with the summary of its JSON.
py::dict analytic_scatter(const py::handle& alpha, double theta, double phi, const std::string& material,
                          const std::string& ndf, int rows, int threads, const py::object& progress) {
  const GGX<double> ggx = ggx_of(alpha);
  const ScatterOptions o = scatter_options(theta, phi, material, 1, 1, 1, rows);
  const NdfKind kind = parse_ndf_kind("ndf", ndf);
  ScatterExpectation e;
  run_interruptible([&](RunControl run) {
    run.threads = threads;
    e = measure_analytic_scatter(kind, {ggx.alpha_x(), ggx.alpha_y()}, o.wi, o.material, rows, run);
  }, progress);
  const DirectionBinning b = DirectionBinning::hemispheres(rows);
  py::array_t<double> order1({py::ssize_t(e.channels()), py::ssize_t(b.rows()), py::ssize_t(b.cols())});
  for (int c = 0; c < e.channels(); ++c)
    std::copy(e.order1[std::size_t(c)].begin(), e.order1[std::size_t(c)].end(), order1.mutable_data(c, 0, 0));
  return py::dict("summary"_a = json_object(scatter_summary_json(e)), "order1"_a = order1, "binning"_a = bin_geometry(b));
}

// `scatter --surface`: every bounce traced on the heightfield.
py::dict scatter_surface(const microgeom::Heightfield& surface, double theta, double phi, const std::string& material,
                         std::uint64_t rays, std::uint64_t seed, int max_order, int rows, int threads,
                         const py::object& progress) {
  const ScatterOptions o = scatter_options(theta, phi, material, rays, seed, max_order, rows);
  return run_scatter(
      [&](const ScatterOptions& options) {
        const HeightfieldScene scene(surface);
        return surface_paths(scene)(options);
      },
      o, threads, progress);
}

// ---- heightfields ------------------------------------------------------------------------------------------------

microgeom::Heightfield heightfield_of(const py::array_t<float, py::array::c_style | py::array::forcecast>& heights,
                                      double tile_size) {
  if (heights.ndim() != 2 || heights.shape(0) != heights.shape(1) || heights.shape(0) < 1)
    throw py::value_error("heights: expected a square (N, N) array");
  if (!(tile_size > 0) || !std::isfinite(tile_size)) throw py::value_error("tile_size must be positive and finite");
  const float* p = heights.data();
  return microgeom::Heightfield(int(heights.shape(0)), tile_size, std::vector<float>(p, p + heights.size()));
}

// `surface build`: a periodic microsurface of an assembly (microgeom/assembly.h); progress as a fraction in
// thousandths, Ctrl-C between the build's steps.
microgeom::Heightfield build_surface(const std::string& assembly, const py::handle& alpha, int resolution,
                                     std::uint64_t seed, double corr_cells, double tile_size, int iterations,
                                     bool check_range, const py::object& progress) {
  microgeom::AssemblyParams p;
  p.assembly = assembly;
  const GGX<double> ggx = ggx_of(alpha);
  p.alpha_x = ggx.alpha_x();
  p.alpha_y = ggx.alpha_y();
  p.resolution = resolution;
  p.seed = seed;
  p.corr_cells = corr_cells;
  p.tile_size = tile_size;
  p.iterations = iterations;
  microgeom::validate(p);
  if (check_range) microgeom::check_supported_range(p);
  std::optional<microgeom::Heightfield> field;
  run_interruptible([&](const RunControl& run) {
    const auto report = [&run](std::string_view stage, double fraction) {
      run.report(stage, std::uint64_t(std::clamp(fraction, 0.0, 1.0) * 1000), 1000);
    };
    field = microgeom::build_assembly(p, nullptr, report, [&run] { return run.cancelled(); });
  }, progress);
  return std::move(*field);
}

void bind_heightfield(py::module_& m) {
  using namespace pybind11::literals;
  using microgeom::Heightfield;
  py::class_<Heightfield>(m, "Heightfield", "A periodic heightfield microsurface: heights on an N x N grid over a tile of side L.")
      .def(py::init(&heightfield_of), "heights"_a, "tile_size"_a,
           "From an (N, N) array of heights (row j, column i: height(i, j)) and the tile's side L.")
      .def_property_readonly("resolution", &Heightfield::resolution, "N, vertices per side")
      .def_property_readonly("tile_size", &Heightfield::tile_size, "L, the tile's side")
      .def_property_readonly("heights", [](py::object self) {
          const Heightfield& f = self.cast<const Heightfield&>();
          const py::ssize_t n = f.resolution();
          // A read-only view of the surface's own heights (no copy), alive as long as the Heightfield.
          py::array_t<float> a({n, n}, f.heights().data(), self);
          py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
          return a;
        }, "The heights as a read-only float32 (N, N) array, row j holding height(i, j) for i = 0..N-1")
      .def_readwrite("metadata", &Heightfield::metadata, "The surface's metadata (assembly, alpha, seed, ...)")
      .def("save", [](const Heightfield& f, const std::string& path) { microgeom::save_heightmap_exr(path, f); },
           "path"_a, "Writes the heightmap EXR (as `microsim surface build --out`).")
      .def("__repr__", [](const Heightfield& f) {
          return "<Heightfield " + std::to_string(f.resolution()) + "x" + std::to_string(f.resolution()) +
                 " tile " + py::repr(py::float_(f.tile_size())).cast<std::string>() + ">";
        });
  m.def("build_surface", &build_surface, "assembly"_a = "smith", "alpha"_a = 0.5, py::kw_only(), "resolution"_a = 1024,
        "seed"_a = 1, "corr_cells"_a = 0.0, "tile_size"_a = 1.0, "iterations"_a = 0, "check_range"_a = true,
        "progress"_a = py::none(),
        R"(Builds a periodic heightfield microsurface (`microsim surface build`): the same heights for the same seed.

assembly: a name of microgeom's registry (smith, ...); alpha: a number or (alpha_x, alpha_y) in [0.005, 2];
resolution: a power of two in [16, 8192]; corr_cells: feature size in cells (0: the default); iterations:
slope-matching iterations (0: the default); check_range: refuse parameters outside the range where a build
meets its own NDF check (--unsupported turns it off on the command line).)");
  m.def("load_heightfield", [](const std::string& path, std::optional<double> tile_size) {
          return microgeom::load_heightmap_exr(path, tile_size);
        }, "path"_a, "tile_size"_a = py::none(),
        "Reads a heightmap EXR (written by `microsim surface build` or Heightfield.save; tile_size for a bare one).");
}

}  // namespace

}  // namespace microsim::python

PYBIND11_MODULE(microsim, m) {
  using namespace microsim::python;
  using namespace pybind11::literals;
  m.doc() = "microsim: a microsurface ray-tracing oracle for Smith-GGX microfacet models, from numpy (docs/guide/python.md).";
  py::register_exception_translator(&translate_errors);
  bind_analytic(m);
  bind_validation(m);
  bind_tables(m);
  bind_battery(m);
  bind_compare(m);
  bind_merge(m);
  bind_heightfield(m);
  m.def("trace_vndf", &trace_vndf, R"(Traces the GGX ellipsoid (the exact VNDF oracle, `microsim trace vndf`).

alpha: a number or (alpha_x, alpha_y); theta, phi: the view in degrees; rays, seed: as the command line
(the same counts for the same seed); rows: rows of the sphere and lobe binnings; mesh_level: -1 for the
exact quadric, else the tessellation level; threads: 0 for all cores; progress: progress(stage, done, total).
Returns a dict: rays, hits, partial, attributes, and binnings {'sphere', 'lobe'}, each with counts,
expected_probability (the analytic D_v per bin), solid_angle, centres (bin centre directions, (rows, cols, 3))
and the parameter-space angles of the centres. On Ctrl-C raises KeyboardInterrupt whose
`partial_result` holds the blocks traced so far.)",
        "alpha"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "rays"_a = 1'000'000, "seed"_a = 1, "rows"_a = 31,
        "mesh_level"_a = -1, "threads"_a = 0, "progress"_a = py::none());
  m.def("trace_surface_vndf", &trace_surface_vndf, "surface"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(),
        "rays"_a = 1'000'000, "seed"_a = 1, "rows"_a = 31, "threads"_a = 0, "progress"_a = py::none(),
        R"(Traces a heightfield's visible normals (`microsim trace vndf --surface`): the dict trace_vndf returns,
with expected_probability Smith's D_v for the surface's reference NDF. Same counts as the command line for the
same surface and seed.)");
  m.def("masking", &masking, "surface"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "samples"_a = 1'000'000, "seed"_a = 1,
        "bins"_a = 10, "theta_l"_a = py::none(), "phi_l"_a = 0.0, "cone"_a = 5.0, "grazing_share"_a = 0.02,
        "geometry"_a = "triangles", "threads"_a = 0, "progress"_a = py::none(),
        R"(Measures masking on a heightfield (`microsim trace masking --surface`): G1(v) with its standard error
beside Smith's (analytic and empirical NDF), by <v, m> and by height; with theta_l, G2(v, l). Returns the
command line's JSON "masking" object as a dict (same values for the same surface and seed). Ctrl-C raises
KeyboardInterrupt whose `partial_result` holds the measurement of the blocks done.)");
  m.def("smith_walk", &smith_walk, "alpha"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "material"_a = "mirror",
        "ndf"_a = "ggx", "heights"_a = "uniform", "walk_kernel"_a = "scalar", "rays"_a = 1'000'000, "seed"_a = 1,
        "max_order"_a = 100, "rows"_a = 16, "threads"_a = 0, "progress"_a = py::none(),
        R"(Multiple scattering in the Smith model by the random walk of Heitz et al. 2016 (`microsim scatter --model
smith-walk`). theta in [0, 90) (from above) or (90, 180] (light from inside a dielectric); material:
'mirror', 'conductor:ETA,K[;ETA,K...]', 'dielectric:ETA' or 'lambertian[:ALBEDO]'; ndf: 'ggx' or 'beckmann';
walk_kernel: 'scalar' (the reference) or 'lanes' (paths in SIMD lanes: GGX, uniform heights, not Lambertian;
the same walk with other random numbers, as `--walk-kernel lanes`).
Returns a dict: summary (the command line's JSON: albedos per order with standard errors, unfinished, lost),
paths, partial, mean_weight and stderr per (channel, order 1..4 and 5+, row, col) of the hemispheres binning,
and binning (its geometry). Same sums as the command line for the same seed.)");
  m.def("analytic_scatter", &analytic_scatter, "alpha"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "material"_a = "mirror",
        "ndf"_a = "ggx", "rows"_a = 16, "threads"_a = 0, "progress"_a = py::none(),
        R"(The exact single scattering (`microsim scatter --model analytic`): the microfacet BSDF's order-1 weight per
launched path in each bin of the hemispheres binning, by cubature. Returns {'summary', 'order1' (channels,
rows, cols), 'binning'}: the expectation smith_walk's and scatter_surface's order 1 estimate.)");
  m.def("scatter_surface", &scatter_surface, "surface"_a, "theta"_a, "phi"_a = 0.0, py::kw_only(), "material"_a = "mirror",
        "rays"_a = 1'000'000, "seed"_a = 1, "max_order"_a = 100, "rows"_a = 16, "threads"_a = 0, "progress"_a = py::none(),
        "Multiple scattering traced bounce by bounce on a heightfield (`microsim scatter --surface`): the dict smith_walk returns.");
  m.def("read_histogram", &read_histogram_file, "path"_a,
        "Reads a histogram EXR written by `microsim trace vndf --out` (or merge): the dict trace_vndf returns.");
  m.attr("__version__") = "0.1";
}
