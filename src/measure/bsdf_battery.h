// measure: the whole battery a renderer's BSDF runs in process (`microsim check-bsdf`, Python
// `microsim.check_bsdf`), against the exact single-scattering BSDF it claims:
//   - per view (battery_views: 0, 30, 60, 80 and 89.9 deg; 120 and 150 deg from inside a dielectric; for an
//     anisotropic roughness views turned off the axes too): its samples' directions
//     against its sampling density, their returned pdfs, and their weights against the BSDF in its convention
//     (validate/dump_validation.h; the lost samples dropped and counted as a renderer drops them), at the
//     family-wise level Sidak-shared over the views;
//   - its consistency with itself: each sample's weight against eval / pdf at the sampled direction, and its
//     returned pdf against pdf(), within 1e-3 relative;
//   - its eval() and pdf() at the pairs of bsdf_queries, pointwise (validate/eval_check.h);
//   - its eval()'s reciprocity at those pairs (a reflection's f(wo, wi) = f(wi, wo); a refraction's ratio the
//     n^2 rule of its transport mode), within 1e-3 relative;
//   - non-finite outputs: a failure;
//   - per view, against itself (bsdf_self_check.h): its directions against its own pdf(), its weighted sample
//     histogram against the integral of its eval() per cell, the white furnace (mean weight against the integral
//     of eval cos) with error bars.
// The reference it claims (BatteryReference): the exact single scattering of the material (the tests above), the
// Smith walk's multiple scattering (its samples and its next-event eval instead of the exact ones), or none (a
// compensated BSDF: only the tests against itself, which hold for any BSDF). A stochastic eval() (an unbiased
// estimate, independent per call) is averaged over repeated calls where a test needs a value with its error,
// and is not held to weight = eval / pdf pointwise.
// The statistical tests share the family-wise level by Sidak's rule.
// The BSDF is called in batches (one view's wi repeated), from the calling thread.
#pragma once

#include "core/run_control.h"
#include "microfacet/bsdf_convention.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "validate/eval_check.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace microsim {

// A BSDF under test, vectorised over n rows: wi and wo unit, z-up; values per channel, row-major.
struct BsdfUnderTest {
  std::string name;
  int channels = 1;
  BsdfConvention convention;
  // wi (n), u (3 n) -> wo (n), pdf (n), weight (channels n), kept (n: 0 for a lost sample).
  std::function<void(std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                     std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept)>
      sample;
  // (wi, wo) (n) -> f(wi, wo) |cos wo| (channels n).
  std::function<void(std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> value)> eval;
  // (wi, wo) (n) -> the density sample() draws wo with (n).
  // Empty: the BSDF has no pdf() (a multiple-scattering sampler's density is not known in closed form).
  std::function<void(std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> pdf)> pdf;
  bool stochastic_eval = false;  // eval() an unbiased noisy estimate, independent from call to call
};

enum class BatteryReference { single_scattering, smith_walk, none };

// A view: wi at polar angle theta from the normal (over 90: from inside) and azimuth phi from the x axis, degrees.
struct BatteryView {
  double theta = 0, phi = 0;
};

// The default grid: theta 0, 30, 60, 80, 89.9 (and 120, 150 from inside a dielectric) at phi 0; for an anisotropic
// roughness (alpha_x != alpha_y) also theta 60 and 80 (120 from inside) at phi 30 and 60: a lobe whose
// anisotropy axes do not stay where the roughness puts them when the view turns (the BSDF rotating the view to
// phi 0 and not the roughness with it) is the same BSDF as the right one at phi 0 and 90.
// A BSDF drawing its normals from D(m) cos leaves 89.9 deg out: its weights grow as 1 / cos theta_i (a conductor's up
// to about 2 / cos^2), and at 89.9 deg a few samples hold most of their spread, which voids the tests of their mean.
std::vector<BatteryView> battery_views(const Material& m, const GGX<double>& ggx,
                                       SampledNormals normals = SampledNormals::visible);
// "60 deg" at phi 0, else "60 deg phi 30".
std::string view_label(const BatteryView& v);

// Why the battery cannot judge a BSDF claiming `claimed` whose sample() draws its normals as `normals` ("" when it
// can): a dielectric sampling D(m) cos has weights too heavy-tailed for the weight tests.
std::string battery_refusal(const Material& claimed, SampledNormals normals);

struct BatteryOptions {
  std::uint64_t samples = 200'000;  // per view
  std::uint64_t seed = 1;
  double level = 0.01;
  Precision arithmetic = Precision::float32;  // of the BSDF, for the eval tolerances
  BatteryReference reference = BatteryReference::single_scattering;
  int points_per_cell = 256;                 // eval() and pdf() points per cell of the integral tests (an even square)
  int eval_repeats = 64;                     // calls per pair of a stochastic eval()
  std::size_t stochastic_pairs = 48;         // query pairs of the stochastic eval and reciprocity tests
  std::uint64_t reference_paths = 4096;      // the walk's paths per pair (its next-event eval)
  int max_order = 100;                       // the walk's order cap (the reference's)
  std::vector<BatteryView> views;            // empty: battery_views()
  RunControl run;
};

struct BatteryLine {
  std::string test, view, detail;
  double p = -1;  // a statistical test's Sidak-adjusted p; -1 for the others
  bool passed = true;
  bool tested = true;  // false: a value reported with nothing to test it against (it cannot fail)
  // The verdict column: "pass", "REJECTED", or "reported" for a line that tested nothing.
  const char* verdict_word() const { return !passed ? "REJECTED" : tested ? "pass" : "reported"; }
};

// The residual per cell of a cell test (bsdf_self_check.h) at one view: (a - lambda b) / sqrt(var a + lambda^2 var b),
// a the samples' histogram, b the integral of eval() or pdf(), lambda = sum a / sum b; NaN where both are empty.
// Cells row-major: rows of z (from -1 up), columns of phi.
struct BatteryResiduals {
  std::string test, view;
  int rows = 0, cols = 0;
  std::vector<double> z;
};

struct BatteryReport {
  std::string convention;  // the BSDF's convention as tested (describe(), bsdf_convention.h)
  std::vector<BatteryLine> lines;
  std::vector<BatteryResiduals> residuals;
  EvalCheckReport eval;
  bool passed = false;
};

// Throws std::invalid_argument when the BSDF's channels are not the material's (or a Lambertian material), on a
// view at 90 deg or out of [0, 180] (from inside, theta > 90, only for a dielectric),
// Cancelled.
BatteryReport run_bsdf_battery(const BsdfUnderTest& bsdf, const Material& claimed, const GGX<double>& ggx,
                               const BatteryOptions& options);

// verdict, tests (one per line) and eval (the pointwise eval check's report; null when it did not run: no exact
// reference).
nlohmann::json to_json(const BatteryReport& report);

}  // namespace microsim
