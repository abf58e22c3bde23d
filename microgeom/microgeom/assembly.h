// microgeom: assemblies of periodic heightfields with a prescribed NDF (Heitz 2018:
// GGX as the normal distribution of a truncated ellipsoid, its facets assembled in other ways). Each assembly is selected by name and is a pure function of its parameters and seed
// (CounterRng streams; FFTW plans with FFTW_ESTIMATE; sorting with index tie-breaks): the same parameters
// give the same heights whatever the thread count.
//
// Common construction (all grids are exactly periodic: integer wavenumbers on the N x N tile):
// - Work in "normalised slope space": the triangle slopes (sx/ax, sy/ay) of the target surface follow the
//   isotropic alpha = 1 law (GGX: P22 with density 1/(pi (1 + r^2)^2); Beckmann: N(0, 1/2) per axis).
//   Anisotropy is obtained by stretching spectra: the starting Gaussian field has correlation lengths
//   (l lambda/ax, l lambda/ay) with lambda = max(ax, ay), i.e. it is the affine image of an isotropic field
//   (the shorter correlation length is l cells); slope targets are scaled back by (ax, ay) and the
//   re-integration weighs x and y residuals by 1/ax^2 and 1/ay^2.
// - Slope-marginal matching (IAAFT-like; design note sec. 4): take the triangle slopes of the current
//   field, replace each normalised slope radius by the GGX quantile of its rank, sqrt(q/(1-q)) with
//   q = rank/(n+1) (ranks from 1), keeping its angle; then re-integrate: the heights minimising the sum over triangles of the squared (weighted) slope residuals,
//   solved exactly in Fourier space (periodic least squares, mean height 0). Iterate.
//
// References: Heitz 2018 JCGT 7(4) (ellipsoid facets, GGX slopes = P22); Heitz 2014 JCGT 3(2) eq. 39
// (P22); Schreiber & Schmitz 1996, Phys. Rev. Lett. 77, "Improved surrogate data for nonlinearity tests"
// (IAAFT: alternate projections onto a marginal and a linear constraint); the Gaussian-scale-mixture form
// of the Student-t (P22 with nu = 2 is N(0, 1/2)/sqrt(E), E ~ Exp(1)).
#pragma once

#include "microgeom/heightfield.h"

#include "core/ndf_kind.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace microgeom {

// The NDF a surface is built to have: the one NDF type of every module (core/ndf_kind.h).
using microsim::NdfKind;

// How the slopes are matched to the reference NDF (docs/reference/surfaces.md, section 8):
// - radial: the slope radii are rank-matched to the reference radius law, the angles kept (the angular law
//   is that of the start field: exact only in expectation);
// - joint: the first half of the iterations match the joint (radius, angle) law to a stratified slope set
//   of the reference (ndf_match.h, match_joint_target), the second half the radius alone (which restores
//   the tail quantiles the joint targets cannot reach: q = 0.999 was 9.7% short at N = 256 with joint
//   targets only, 1.4% with half radial), then a final refinement of the vertex heights brings the triangle
//   counts and mean slopes of the lobe bins of `trace vndf`, the counts of its sphere bins and of 1024
//   radius bins to the reference law (refine_binned_ndf). Applies to the Beckmann control too (otherwise only rescaled).
enum class NdfMatch { radial, joint };
std::string_view to_string(NdfMatch m);
// "radial" or "joint"; nullopt for any other text.
std::optional<NdfMatch> ndf_match_from_string(std::string_view name);

// What build_assembly does to the Gaussian random field before its slopes are matched.
enum class AssemblyShaping {
  none,
  roughness_patches,  // Beckmann patches of roughness alpha/sqrt(E), E ~ Exp(1): a Gaussian scale mixture
  sorted_by_height,   // facets sorted by height, the steep ones low (in pits)
};

// An assembly and how it is built: a Gaussian random field, shaped, then, for a GGX reference, its
// slopes matched to GGX (for the Beckmann reference, rescaled to its slope second moment), then
// optionally turned upside down.
struct AssemblyInfo {
  std::string name;
  std::string summary;    // one sentence, for --help and the docs
  NdfKind reference;      // the NDF the surface is built to have (and is checked against)
  AssemblyShaping shaping = AssemblyShaping::none;
  bool upside_down = false;  // heights negated at the end
};
const std::vector<AssemblyInfo>& assembly_registry();
const AssemblyInfo* find_assembly(std::string_view name);
// The plain assembly of an NDF (no shaping, not upside down): "smith" for GGX, "beckmann" for Beckmann.
std::string_view plain_assembly(NdfKind ndf);
// The names of the registry, in its order, joined by `separator`.
std::string assembly_names(std::string_view separator);

inline constexpr double kMinAssemblyAlpha = 0.005;
inline constexpr double kMaxAssemblyAlpha = 2.0;
inline constexpr int kMinAssemblyResolution = 16;
inline constexpr int kMaxAssemblyResolution = 8192;  // ~2 GiB at the peak (radial; build_assembly)

struct AssemblyParams {
  std::string assembly = "smith";
  double alpha_x = 0.5, alpha_y = 0.5;
  int resolution = 1024;       // N, a power of two in [16, 8192]
  std::uint64_t seed = 1;
  double corr_cells = 0;       // feature size l in cells; 0 -> default_corr_cells(N)
  double tile_size = 1.0;      // L, physical units
  int iterations = 0;          // marginal-matching iterations; 0 -> kDefaultIterations
  NdfMatch ndf_match = NdfMatch::radial;
};

inline constexpr int kDefaultIterations = 8;
// min(16, N/16): l >= 16 keeps the finite-difference slope bias near 0.1% (design note sec. 4) while the
// tile stays >= 16 correlation lengths.
double default_corr_cells(int resolution);

// Throws std::invalid_argument naming the bad value: unknown assembly, alpha outside
// [kMinAssemblyAlpha, kMaxAssemblyAlpha] or not finite, resolution not a power of two or out of range,
// corr_cells < 2 or > N/8, tile size <= 0, iterations < 0 or > 100.
void validate(const AssemblyParams& params);

// ---- the supported range: where a build meets its own NDF check ------------------------------------------
// validate() states what can be built at all; the supported range is the part of it where the built tile
// meets its NDF check (surface_stats.h, tolerance_for) with a margin, measured over seeds by
// scripts/surface_range.sh (docs/reference/surfaces.md, "Supported range", has the tables). Outside it a build
// fails its own check, or passes by luck of the seed, so `surface build` refuses it before any work.
// Isotropic alpha does not enter: the construction works in normalised slope space, and alpha in
// [0.005, 2] gives identical verdicts.
// - GGX assemblies need N >= 256: at N <= 64 (<= 8192 triangles) the re-integrated slope radii miss the
//   fixed 3% quantile / radius-bin bounds at every alpha and correlation length (3.4-56%, 3 seeds); at
//   N = 128 they reach 2.5% isotropic and 3.4% at 1:4 (1 of 24 builds fails; 3 of 12 with l = N/8).
//   N = 256 is also where the tolerance's calibration starts. The Beckmann control, whose bounds widen
//   with the sampling noise, meets its check from N = 16.
// - Anisotropy max/min alpha <= 4: stretching the spectrum to 1:r leaves (N/l)^2 / r independent patches
//   while the angular-bin tolerance counts (N/l)^2 (the angular law of one tile is exact only in
//   expectation), so the angular error grows with r at every N: largest error / tolerance 0.57 at 1:4,
//   0.96 at 1:6 and 1.18 at 1:8 (mixture, N = 1024, 2 seeds); 1:10 fails at N = 128 and 1:20 at
//   N = 512 for most assemblies; 1:400 (alpha 0.005,2) fails at every N measured (128-1024) and assembly.
// - Correlation length l >= min_checked_corr_cells(N) = min(8, max(N >= 256 ? 4 : 2, N/128)) cells: on
//   the grid, short features bias the angular law (11-17% per bin at l = 2, 5-8% at l = 3, 4-5% at
//   l = 4, N = 1024), beyond the angular tolerance max(5%, 5 sqrt(32) l/N) at large N (l = 2 fails at
//   N >= 512; at N = 256 it reaches 0.98 of it). And for the GGX assemblies l <= N/16 (at l = N/8 the
//   radius bins reach 0.96 of their bound at 1:4). The default l = min(16, N/16) is always inside.
inline constexpr int kMinGgxCheckedResolution = 256;
inline constexpr double kMaxCheckedAnisotropy = 4;
inline constexpr double kMinGgxCorrelationLengthsPerTile = 16;
double min_checked_corr_cells(int resolution);

// The build cannot meet its NDF check: a std::invalid_argument whose message names the value and what
// would work.
class OutsideSupportedRange : public std::invalid_argument {
public:
  using std::invalid_argument::invalid_argument;
};

// Throws OutsideSupportedRange unless `params` (valid: see validate()) lie in the supported range above.
// The message names the bad value in library terms ("resolution 64", "alpha (0.005, 2)", "correlation
// length 2 cells") and what would work.
void check_supported_range(const AssemblyParams& params);

struct BuildReport {
  double corr_cells = 0;
  int iterations = 0;
  // Per marginal-matching iteration: mean |normalised slope of the re-integrated surface - target| over
  // triangles, divided by the mean |target| (0 = the matched slopes were exactly integrable).
  std::vector<double> residuals;
  std::vector<std::string> notes;  // construction details (e.g. the mixture's patch size)
  // The final refinement of NdfMatch::joint (zero otherwise): sweeps, accepted vertex moves, and the
  // binned discrepancy before and after (ndf_match.h, refine_binned_ndf).
  int refine_sweeps = 0;
  std::uint64_t refine_moves = 0;
  double refine_objective_before = 0, refine_objective_after = 0;
};

// (stage, fraction of the whole build done in [0, 1]); called from the building thread.
using BuildProgress = std::function<void(std::string_view stage, double fraction)>;

// Polled between the steps of a build (noise, each half of each slope-matching iteration): returning
// true abandons the build. Called from the building thread.
using BuildCancel = std::function<bool()>;

// Thrown by build_assembly when `cancelled` returned true: no surface was built.
struct BuildCancelled : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Builds the surface (heights in the unit of tile_size, mean 0). Metadata: assembly, alpha, seed,
// corr_cells, iterations, reference, ndf_match. Validates first. Memory at the peak: 24 bytes per texel with
// NdfMatch::radial (three buffers of N (N + 2) doubles, the heights in one; slopes and targets are computed
// from them, ranks sorted in blocks), about 90 with NdfMatch::joint (its slope, key and stratum arrays).
// Throws BuildCancelled when `cancelled` asks to stop.
Heightfield build_assembly(const AssemblyParams& params, BuildReport* report = nullptr,
                           const BuildProgress& progress = {}, const BuildCancel& cancelled = {});

namespace detail {
// Sorts 64-bit keys by their upper 32 bits, stably (an LSD radix sort, 4 passes of 8 bits, parallel over
// a fixed number of chunks, so the result does not depend on the thread count; a pass whose digit is the
// same for every key is skipped). Keys packed as
// (value bits << 32 | index) and given in index order thus end up sorted by (value, index). `scratch` is
// resized to keys.size(). O(n); used for the ranks of the slope matching and of the statistics.
void radix_sort_by_high32(std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& scratch);
// The same on n keys at `keys`, with n keys of scratch space at `scratch` (the result in `keys`).
void radix_sort_by_high32(std::uint64_t* keys, std::uint64_t* scratch, std::size_t n);
}  // namespace detail

}  // namespace microgeom
