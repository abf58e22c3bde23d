// validate --model smith-walk (validate_walk.h).
#include "validate_walk.h"

#include "command.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "measure/walk_validation.h"
#include "microfacet/roughness.h"

#include <fmt/core.h>

#include <cmath>

namespace microsim::app {
namespace {

constexpr long long kDefaultWalkPaths = 2'000'000;

DirectionSampleReader open_dump(const WalkValidationArgs& a) {
  try {
    DirectionSampleReader reader(a.from, SampleColumns::parse(a.columns.empty() ? "x,y,z,weight" : a.columns));
    reader.set_frame(a.frame == "y-up" ? SampleFrame::y_up : SampleFrame::z_up);
    return reader;
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--columns: {}", e.what()));
  } catch (const SampleFileError& e) {
    throw UsageError(e.what());
  }
}

void print_report(const WalkValidationArgs& a, const WalkValidationReport& r, const Material& m) {
  fmt::print("validate --model smith-walk: {} ({} rows) against the Smith random walk ({} paths), {}, alpha {}, theta {} "
             "deg\n", a.from, r.rows, r.paths, m.describe(), a.alpha, a.theta);
  const auto e = [](const Estimate& x) { return fmt::format("{:.5f} +- {:.5f}", x.value, x.standard_error); };
  fmt::print("  reflected albedo:   dump {}  walk {}  p = {:.3g}\n", e(r.albedo_reflected_dump), e(r.albedo_reflected_walk),
             r.p_reflected);
  if (m.transmits())
    fmt::print("  transmitted albedo: dump {}  walk {}  p = {:.3g}\n", e(r.albedo_transmitted_dump),
               e(r.albedo_transmitted_walk), r.p_transmitted);
  fmt::print("  lobe shape: TV {:.4f} (noise floor {:.4f}), chi-square p = {:.3g}\n", r.tv, r.tv_noise_floor, r.chi2->p_value);
  fmt::print("  the walk's weight left at its order cap: {:.2g}\n", r.walk_unfinished.value);
  for (const std::string& f : r.failures) fmt::print("  failure: {}\n", f);
  fmt::print("{} (p = {:.3g}, {} tests at family-wise level {}, Sidak)\n", r.passed ? "PASSED" : "REJECTED", r.p_value,
             r.tests, a.significance);
}

}  // namespace

int run_walk_validation(const WalkValidationArgs& a) {
  check_distinct_outputs({{"--from", a.from}}, {{"--json", a.json}});
  check_output("--json", a.json);
  if (a.material.empty()) throw UsageError("--model smith-walk needs --material (e.g. dielectric:1.5, conductor:0.2,3.9)");
  const Material material = parse_material("--material", a.material);
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const bool inside = a.theta > 90 && a.theta <= 180;
  if (!(a.theta >= 0 && a.theta < 90) && !(inside && material.transmits()))
    throw UsageError(fmt::format("--theta {}: [0, 90), or (90, 180] from inside a dielectric", a.theta));
  if (a.frame != "" && a.frame != "z-up" && a.frame != "y-up") throw UsageError(fmt::format("--frame {}: z-up or y-up", a.frame));
  DirectionSampleReader dump = open_dump(a);
  WalkValidationOptions o;
  o.paths = std::uint64_t(a.paths.value_or(kDefaultWalkPaths));
  o.seed = a.seed;
  o.significance = a.significance;
  o.dropped = std::uint64_t(a.dropped.value_or(0));
  install_interrupt_handler();
  o.run = cli_run_control(0, nullptr);
  const double t = a.theta * kPi<double> / 180, p = a.phi * kPi<double> / 180;
  const Vec3<double> wi(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
  WalkValidationReport r;
  try {
    r = validate_dump_against_walk(dump, SmithMicrosurface{WalkNdf::ggx, ax, ay}, material, wi, o);
  } catch (const SampleFileError& e) {
    throw UsageError(e.what());
  } catch (const InsufficientData& e) {
    throw UsageError(fmt::format("--from '{}': {}", a.from, e.what()));
  } catch (const Cancelled&) {
    return interrupted_nothing_written("validate", "during the walk");
  }
  if (!a.json.empty()) write_file_atomically(a.json, to_json(r).dump(2) + "\n");
  print_report(a, r, material);
  return r.passed ? kExitOk : kExitRejected;
}

}  // namespace microsim::app
