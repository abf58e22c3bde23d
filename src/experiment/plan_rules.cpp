// experiment: the planner's decision rules, as pure functions (plan.h).
#include "experiment/measurement.h"

#include "core/random.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace microsim::experiment {

std::string to_string(Model model) {
  switch (model) {
    case Model::analytic: return "analytic";
    case Model::ellipsoid_oracle: return "ellipsoid-oracle";
    case Model::smith_walk: return "smith-walk";
    case Model::heightfield: return "heightfield";
    case Model::analytic_validator: return "analytic-validator";
  }
  return "?";
}

namespace {

// The noncentrality at which a chi-square test of `dof` at `significance` rejects with probability `power`:
// the noncentral chi-square (Boost.Math) whose miss probability at the critical value is 1 - power.
double needed_noncentrality(int dof, double significance, double power) {
  if (dof < 1 || !(significance > 0 && significance < 1) || !(power > significance && power < 1))
    throw std::invalid_argument(fmt::format("validation power: df {}, significance {}, power {}", dof, significance, power));
  const double critical = boost::math::quantile(boost::math::complement(boost::math::chi_squared(dof), significance));
  return boost::math::non_central_chi_squared::find_non_centrality(double(dof), critical, 1 - power);
}

}  // namespace

ModelChoice choose_model(const SpecQuantity& q, const SpecMaterial& m) { return kind_model_rule(q.kind)(q, m); }

ModelChoice explicit_surface_choice(const SpecQuantity& q) {
  const std::string what = q.surface.kind == SurfaceChoice::Kind::assembly ? "assembly " + q.surface.name
                                                                            : "heightmap " + q.surface.name;
  return {Model::heightfield, fmt::format("the spec names a surface ({}): its own effects (conditional masking, "
                                          "its multiple scattering, the assembly's correlations) are only in the "
                                          "explicit heightfield",
                                          what)};
}

ModelChoice smith_orders_choice(const SpecQuantity& q, const std::string& note) {
  if (q.orders == Orders::single)
    return {Model::analytic, "single scattering on the Smith microsurface has a closed form (Walter et al. 2007 with "
                             "Smith masking): integrated by quadrature, no noise, no explicit surface needed" + note};
  return {Model::smith_walk, "multiple scattering in the Smith model: the Smith random walk (Heitz et al. 2016) is "
                             "that model exactly, with no surface to build or trace" + note};
}


std::uint64_t units_for_standard_error(std::uint64_t pilot_units, double pilot_se, double target_se) {
  if (!(target_se > 0)) throw std::invalid_argument(fmt::format("target standard error {} must be > 0", target_se));
  if (pilot_units == 0) throw std::invalid_argument("a pilot of 0 units");
  if (!(pilot_se > 0)) return pilot_units;
  const double ratio = pilot_se / target_se;
  const double n = std::ceil(double(pilot_units) * ratio * ratio);
  const double cap = double(std::numeric_limits<std::uint64_t>::max() / 2);
  return n >= cap ? std::uint64_t(cap) : std::max<std::uint64_t>(1, std::uint64_t(n));
}

std::uint64_t next_round_units(std::uint64_t done, double achieved, double target) {
  if (achieved <= target || done == 0) return 0;
  const std::uint64_t needed = units_for_standard_error(done, achieved, target);
  const double more = std::ceil(double(needed - std::min(needed, done)) * kRoundMargin);
  return std::max<std::uint64_t>(std::uint64_t(more), std::max<std::uint64_t>(1, done / 4));
}

std::optional<int> order_cap_for(const std::vector<CapProbe>& probes, double threshold) {
  for (const CapProbe& p : probes)
    if (p.unfinished + 2 * p.unfinished_se < threshold) return p.cap;
  return std::nullopt;
}

std::uint64_t validation_samples(double detect_tv, int degrees_of_freedom, double significance, double power) {
  if (!(detect_tv > 0 && detect_tv < 1))
    throw std::invalid_argument(fmt::format("validation_samples: tv {}, df {}, significance {}, power {}", detect_tv,
                                            degrees_of_freedom, significance, power));
  const double needed = std::ceil(needed_noncentrality(degrees_of_freedom, significance, power) / (4 * detect_tv * detect_tv));
  if (!(needed <= double(kMaxSamples)))
    throw std::invalid_argument(fmt::format("detect_tv {} needs {:.3g} samples, more than the {:.0e} a validation can "
                                            "draw", detect_tv, needed, double(kMaxSamples)));
  return std::max(std::uint64_t(needed), 5 * std::uint64_t(degrees_of_freedom + 1));
}

double detectable_tv(std::uint64_t samples, int degrees_of_freedom, double significance, double power) {
  if (samples == 0) throw std::invalid_argument("detectable_tv: 0 samples detect nothing");
  return std::sqrt(needed_noncentrality(degrees_of_freedom, significance, power) / (4 * double(samples)));
}

ValidationTests validation_tests(int rows, double significance) {
  return {2 * rows * rows - 1, 1 - std::sqrt(1 - significance)};
}

double predicted_seconds(std::uint64_t units, std::uint64_t pilot_units, double pilot_seconds) {
  if (pilot_units == 0 || !(pilot_seconds > 0)) return 0;
  return pilot_seconds * double(units) / double(pilot_units);
}

std::uint64_t derived_seed(std::uint64_t seed, std::uint64_t purpose, std::uint64_t index) {
  return CounterRng(seed, mix64(purpose * 0x9e3779b97f4a7c15ULL + index)).next_u64();
}

}  // namespace microsim::experiment
