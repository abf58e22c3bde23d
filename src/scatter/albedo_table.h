// scatter: energy-compensation reference tables: the directional albedo E(mu, alpha) of a rough
// mirror, conductor (one complex index per table, and its Fresnel average F_avg) or dielectric and its
// hemispherical average
//   E_avg(alpha) = 2 integral_0^1 E(mu) mu dmu,
// the two tables of Kulla & Conty 2017 ("Revisiting Physically Based Shading at Imageworks", SIGGRAPH
// course, sec. "Energy compensation": E(mu) and E_avg; for a dielectric, from outside and from inside, i.e.
// eta and 1/eta), from three models:
//   analytic    single scattering by quadrature: E1(wi) = integral of f(wi, wo) |cos o| dwo over the sphere
//               (f: single_scattering_flux, scatter/analytic_scatter.h: Walter et al. 2007 with the Smith
//               microsurface's own masking), substituted into the visible normals (below); error: the
//               quadrature's error estimate;
//   smith-walk  the Smith random walk (Heitz, Hanika, d'Eon, Dachsbacher 2016; scatter/smith_walk.h): every
//               order, and order 1 (the single scattering it shares with the analytic model); standard errors;
//   surface     the explicit heightfield (microgeom build_assembly, assembly "smith" for GGX, "beckmann" for
//               Beckmann, at that alpha; scatter_on_surface): every order, order 1, paths lost; standard
//               errors of the path sampling (one surface realisation per alpha: its own variance is not in
//               the error).
//
// The analytic E1 per cell: with wo = reflect(wi, m) (dwo = 4 |wi.m| dm, Walter et al. 2007 eq. 14) or
// wo = refract(wi, m) (dwo = (eta_i wi.m + eta_o wo.m)^2 / (eta_o^2 |wo.m|) dm, eq. 17), and m = m(u) the
// exact visible-normal sampler of wi (Heitz 2018 for GGX, the exact slope inversion for Beckmann) whose pdf
// D_wi(m) is dm/du's inverse,
//   E1_R = integral over [0,1]^2 of f |cos o| 4 |wi.m| / D_wi(m) du,   E1_T likewise with the refraction's
// Jacobian: a bounded integrand (F G2 / G1 once the factors cancel) whatever alpha, with no narrow lobe to
// find. Its kinks (a reflection or refraction crossing the horizon, G2 -> 0) and square-root points (the
// facet's critical angle from inside) lie on curves in u: each line u1 = const is cut at their crossings
// (roots on a 32-point scan, pairs between scan points found from |g|'s minima, TOMS 748), and u1 where a
// curve touches a line (a kink of the inner integral); every piece goes through the smoothstep
// u = a + (b - a)(3t^2 - 2t^3) and is integrated by global adaptive Gauss-Kronrod (15 points, Gauss 7
// embedded; QUADPACK's QAG strategy with a budget of intervals). Error estimate: the sum of |Kronrod -
// Gauss| over the outer rule's final intervals plus the outer integral of the inner estimates. It is an
// estimate, not a bound: against a tolerance-1e-12 run (GGX, alpha 0.02..1.5, mu 0.03..0.97, mirror and
// dielectric 1.5 from both sides, 177 values per tolerance) it was exceeded once per tolerance, by at
// most 2.4 times (1e-4, 1e-6, 1e-8; docs/guide/scattering-and-energy-tables.md).
//
// The mu grid: the Gauss-Legendre nodes of [0, 1] (mus of them, increasing), so that
//   E_avg = 2 sum_j w_j mu_j E(mu_j)
// is exact for E mu a polynomial of degree 2 mus - 1. Its error: sampled models, the cells are independent
// (cell (a, m) draws from its own seed, albedo_cell_seed), so SE(E_avg) = 2 sqrt(sum_j (w_j mu_j SE_j)^2);
// analytic, the cells' error estimates add: 2 sum_j w_j mu_j err_j. Neither includes the mu rule's own
// error (docs/records/scattering.md measures it: the 16-node table's E_avg against 64 nodes).
//
// Engine: rows (alphas) are filled in order; the analytic cells of a row run in parallel (run.threads),
// a sampled cell runs its paths on the block runner. Cell results depend only on (request, cell): the
// same seed gives the same table whatever the thread count. A cancelled run (run.cancel) returns the rows
// completed before it, marked partial (a row in progress is dropped). Never prints.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "microfacet/beckmann.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "scatter/scatter_setup.h"
#include "scatter/smith_walk.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

enum class AlbedoModel { analytic, smith_walk, surface };
std::string to_string(AlbedoModel model);  // "analytic", "smith-walk", "surface"
// "analytic" / "smith-walk" / "surface"; ParseError naming `what` and quoting the text otherwise.
AlbedoModel parse_albedo_model(std::string_view what, std::string_view text);

inline constexpr int kMinAlbedoMus = 2;
inline constexpr int kMaxAlbedoMus = 256;
// Roughness of a table: the assemblies' range (microgeom/assembly.h), the same for every model.
inline constexpr double kMinAlbedoAlpha = 0.005;
inline constexpr double kMaxAlbedoAlpha = 2.0;

struct AlbedoTableRequest {
  AlbedoModel model = AlbedoModel::analytic;
  NdfKind ndf = NdfKind::ggx;
  Material material = Material::mirror();  // mirror, dielectric or a one-channel conductor
  bool inside = false;                     // light from inside the dielectric (wi.z < 0)
  std::vector<double> alphas{0.1, 0.25, 0.5, 0.75, 1.0};  // isotropic; increasing, in [kMinAlbedoAlpha, kMaxAlbedoAlpha]
  int mus = 16;                            // Gauss-Legendre nodes, in [kMinAlbedoMus, kMaxAlbedoMus]
  double tolerance = 1e-8;                 // analytic: absolute error target of each cell, in [1e-13, 1e-2]
  std::uint64_t paths = 1'000'000;         // sampled: paths per cell
  std::uint64_t seed = 1;                  // sampled: cell seeds (albedo_cell_seed); surface: the build's seed
  int max_order = kDefaultMaxOrder;        // sampled: the order cap
  int resolution = 512;                    // surface: vertices per side (microgeom's supported range)
  // smith-walk: the code that walks each cell's paths (scatter/smith_walk.h); lanes for GGX only. Another
  // kernel, other random numbers: a table of the same walk, not the same bits.
  WalkKernel walk_kernel = WalkKernel::scalar;
  // Threads and cancel token of every step; progress: "albedo table" (cells, or paths for the sampled
  // models, of the whole table) and "build surface" (thousandths of one build).
  RunControl run;
};

// Throws std::invalid_argument naming the bad value: a material other than mirror, dielectric or a conductor
// of one channel (one complex index: a table per channel), inside on
// a mirror, no alphas or alphas not increasing or out of range, mus out of range, tolerance out of range,
// paths 0, max_order outside [1, kMaxOrderCap], a surface resolution outside microgeom's supported range.
void check_albedo_request(const AlbedoTableRequest& request);

// The quantities a table of this model and material holds, in order (AlbedoQuantity::name):
//   E, E_R, E_T     all orders: total, reflected (back to wi's side), transmitted (sampled models)
//   E1, E1_R, E1_T  order 1 (every model; the analytic model has only these)
//   unfinished      the weight left at the order cap (sampled); lost: paths the tracer lost (surface)
// A mirror has no _R / _T split (all is reflected).
std::vector<std::string> albedo_quantity_names(AlbedoModel model, const Material& material);

// One quantity: per cell (row-major: cells[a * mus + m]) and per alpha its E_avg, each with its error (a
// standard error, or the analytic quadrature's error estimate: AlbedoTable::error_kind).
struct AlbedoQuantity {
  std::string name;
  std::vector<Estimate> cells;
  std::vector<Estimate> average;
};

struct AlbedoTable {
  AlbedoTableRequest request;           // as given (its RunControl is not part of the result)
  std::vector<double> alphas;           // rows: the completed prefix of request.alphas
  std::vector<double> mus, mu_weights;  // columns: Gauss-Legendre nodes of [0, 1] and weights (sum 1)
  std::vector<AlbedoQuantity> quantities;
  bool partial = false;                 // cancelled before every row was complete
  std::vector<double> row_seconds;      // wall time per completed row (a surface row includes its build)
  std::vector<double> build_seconds;    // surface: the build and scene of each completed row
  double seconds = 0;                   // the whole call
  std::optional<double> fresnel_average;  // a conductor's F_avg (fresnel_average), for the Kulla-Conty Fresnel term

  std::string error_kind() const;  // "quadrature error estimate" or "standard error"
  const AlbedoQuantity* find(std::string_view name) const;  // nullptr if the table has no such quantity
  Estimate cell(std::string_view quantity, std::size_t alpha_index, std::size_t mu_index) const;  // throws out_of_range
};

// A conductor's hemispherical Fresnel average F_avg = 2 int_0^1 F(mu) mu dmu (Kulla & Conty 2017, the
// Fresnel factor of the multiple-scattering term, F_avg^2 E_avg / (1 - F_avg (1 - E_avg))), of its channel 0,
// by Gauss-Legendre quadrature on kFresnelAverageNodes nodes (F is smooth in mu: exact to rounding).
// Throws std::invalid_argument for another material.
inline constexpr int kFresnelAverageNodes = 64;
double fresnel_average(const Material& material);

// Gauss-Legendre nodes and weights on [0, 1] (n >= 1): nodes increasing, weights summing to 1; exact for
// polynomials of degree 2n - 1 (Boost.Math legendre_p_zeros, weights 2 / ((1 - x^2) P_n'(x)^2) halved).
struct MuGrid {
  std::vector<double> mus, weights;
};
MuGrid gauss_legendre_mus(int n);

// The seed of cell (alpha_index, mu_index) of a sampled table: a CounterRng draw keyed by (seed, cell), so
// that cells are independent streams.
std::uint64_t albedo_cell_seed(std::uint64_t seed, std::size_t alpha_index, std::size_t mu_index);
// The walk of one cell of a sampled table: light along -wi, `paths` from `seed` (the cell's albedo_cell_seed),
// capped at `max_order`, one row per hemisphere (a table reads the order bins' totals), on the run's threads and
// cancellation, its progress reported to `run` (which must outlive the options) as `label`, from `before` of
// `total` paths of the whole table.
ScatterOptions albedo_cell_walk(const Vec3<double>& wi, std::uint64_t paths, std::uint64_t seed, int max_order,
                                const RunControl& run, const char* label, std::uint64_t before, std::uint64_t total);

// The direction toward the light of a table's column: (sqrt(1 - mu^2), 0, mu), z negated from inside.
Vec3<double> albedo_view(double mu, bool inside);

// Single-scattering albedo of one view, split into the light reflected (back to wi's side) and transmitted
// (a dielectric's other side), each with its quadrature error estimate (in standard_error), for light along
// -wi (unit, off the horizon; wi.z < 0 only for a dielectric). material: mirror, conductor (channel) or
// dielectric. `tolerance`: the absolute error target of each side.
// The masking of a dielectric's refraction lobe: the Smith microsurface's own (transmission_G2,
// microfacet/bsdf.h: what order 1 of the Smith walk is, and this module's tables), or Walter et al. 2007's
// reflection form 1 / (1 + Lambda_i + Lambda_o) for both lobes, which renderers evaluate (dielectric_bsdf;
// Blender Cycles' bsdf_microfacet_eval and so its rough-glass tables).
enum class RefractionMasking { smith_microsurface, height_correlated };
struct SingleScatteringAlbedo {
  Estimate reflected, transmitted;
  long long evaluations = 0;  // integrand evaluations
  Estimate total() const;     // reflected + transmitted, errors added
};
SingleScatteringAlbedo single_scattering_albedo(
    const GGX<double>& ggx, const Material& material, int channel, const Vec3<double>& wi, double tolerance,
    RefractionMasking masking = RefractionMasking::smith_microsurface);
SingleScatteringAlbedo single_scattering_albedo(
    const Beckmann<double>& beckmann, const Material& material, int channel, const Vec3<double>& wi,
    double tolerance, RefractionMasking masking = RefractionMasking::smith_microsurface);

// The two integrals of a GGX mirror's single scattering that Schlick's Fresnel F = f0 + (1 - f0) (1 - wo.m)^5
// splits into (Karis 2013, "Real Shading in Unreal Engine 4"; Filament's DFG LUT in its multiscatter form,
// google/filament libs/ibl/src/CubemapIBL.cpp DFV_Multiscatter): unit = E of F = 1 (DFG.y), grazing = the
// albedo with the facet weight (1 - wo.m)^5 (DFG.x), so that E(f0) = f0 unit + (1 - f0) grazing. Both with the
// height-correlated Smith G2 of the mirror (the reflection form 1 / (1 + Lambda_i + Lambda_o), Heitz 2014
// eq. 99), by the quadrature of single_scattering_albedo (one pass, both integrands: their own error estimates).
// std::invalid_argument as single_scattering_albedo for a bad view or tolerance (wi.z > 0 required).
struct SchlickSplitAlbedo {
  Estimate unit, grazing;
  long long evaluations = 0;
};
SchlickSplitAlbedo schlick_split_albedo(const GGX<double>& ggx, const Vec3<double>& wi, double tolerance);

// The same two integrals (unit: E of F = 1; grazing: weighted by (1 - wi.m)^5) for an isotropic Beckmann mirror
// seen from albedo_view(mu, false), integrated in the view's visible slopes instead of through the sampler's
// unit square (whose Beckmann inverse CDF costs a root-finding per point, and whose kinks must be searched for).
// In the stretched (alpha = 1) configuration of a view at theta_i, the visible slopes (x, y) of Beckmann have
// the density (Heitz & d'Eon 2014, sec. 4 and appendix; Heitz 2014 eq. 16 with Walter et al. 2007 eq. 25)
//   q(x, y) = w(x) exp(-y^2) / sqrt(pi),  w(x) = (a - x)+ exp(-x^2) / N,  a = cot(theta_i) / alpha,
//   N = exp(-a^2) / 2 + a sqrt(pi) erfc(-a) / 2,
// with the normal m = (-alpha x, -alpha y, 1) / |.|. A mirror's single scattering is E = int D_wi(m) G2 / G1(wi)
// dm (Walter et al. 2007 eq. 14: dwo = 4 |wi.m| dm; G2 height-correlated, Heitz 2014 eq. 99, Lambda Walter
// et al. eq. 27), and wo = reflect(wi, m) is above the horizon exactly inside the disk
//   (alpha x + tan theta_i)^2 + (alpha y)^2 < sec^2 theta_i
// (from wo.z = 2 (wi.m) m.z - wi.z; the disk lies inside the visible half-plane x < a). So, h even in y,
//   E = int_{x_lo}^{x_hi} w(x) 2 int_0^{Y(x)} exp(-y^2) / sqrt(pi) h(x, y) dy dx,
//   x_lo,hi = (-tan theta_i -+ sec theta_i) / alpha,  Y(x) = sqrt(sec^2 - (alpha x + tan)^2) / alpha:
// every kink of the integrand is an end of an interval, known in closed form (a square-root end of the outer
// integrand where Y -> 0), nothing to search for, no inverse CDF. The Gaussian tails beyond |x|, |y| = 9 are
// left out (below erfc(9) / 2 < 1e-36). Both integrals by the quadrature of single_scattering_albedo (each
// interval through the smoothstep, global adaptive Gauss-Kronrod 15/7), and the same error estimate: the outer
// |Kronrod - Gauss| plus the outer integral of the inner ones. alpha below kMinAlpha is computed at kMinAlpha
// (Beckmann's clamp); mu in (0, 1] (std::invalid_argument otherwise, or for a tolerance that is not positive).
SchlickSplitAlbedo beckmann_mirror_split(double alpha, double mu, double tolerance);

// Called after each completed row (on the calling thread) with the table so far and the row's index.
using AlbedoRowCallback = std::function<void(const AlbedoTable& so_far, std::size_t row)>;

// Fills the table of the request (check_albedo_request first; throws what it throws, std::invalid_argument).
AlbedoTable albedo_table(const AlbedoTableRequest& request, const AlbedoRowCallback& on_row = {});

// A walk table's cells split over processes (`mpirun`, a job array: experiment/split_rounds.h). Cell c is
// (alpha c / mus, mu c % mus), row-major; each is its own walk of request.paths paths from its own seed
// (albedo_cell_seed), so any split of the cells gives the table albedo_table gives, bit for bit.
using AlbedoCells = std::vector<std::vector<Estimate>>;  // per cell: its quantities (albedo_quantity_names)
// The cells [cells.begin, cells.end) of a Smith-walk table; nullopt when cancelled. Throws
// std::invalid_argument for another model, a bad request (check_albedo_request) or cells beyond the table.
std::optional<AlbedoCells> walk_albedo_cells(const AlbedoTableRequest& request, const BlockRange& cells);
// The paths of one cell of a surface table: row `row`'s surface (alpha row; its caller builds or reads it)
// traced with `options` (the cell's view, seed and paths: scatter_on_surface on that surface's scene).
using AlbedoSurfacePaths = std::function<ScatterHistogram(std::size_t row, const ScatterOptions& options)>;
// The cells [cells.begin, cells.end) of a surface table whose rows' surfaces `paths` traces (each cell from
// its own seed, as a walk's: any split gives the same cells). The request's resolution and seed are not used
// (the surfaces are the caller's). nullopt when cancelled; throws as walk_albedo_cells for another model.
std::optional<AlbedoCells> surface_albedo_cells(const AlbedoTableRequest& request, const BlockRange& cells,
                                                const AlbedoSurfacePaths& paths);
// The table of every cell (alphas x mus of them, in order), as albedo_table computes it from them; `seconds`
// the time they took (row_seconds: its share per row). Throws std::invalid_argument for a wrong count.
AlbedoTable albedo_table_from_cells(const AlbedoTableRequest& request, const AlbedoCells& cells, double seconds);

}  // namespace microsim
