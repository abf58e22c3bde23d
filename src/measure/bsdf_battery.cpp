// The whole battery of a renderer's BSDF in process (bsdf_battery.h).
#include "measure/bsdf_battery.h"

#include "core/random.h"
#include "measure/bsdf_self_check.h"
#include "stats/chi2.h"
#include "validate/bsdf_queries.h"
#include "validate/dump_validation.h"
#include "validate/sample_io.h"

#include <fmt/core.h>

#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

constexpr std::size_t kBatch = 65536;
constexpr double kConsistency = 1e-3;  // relative

using Samples = battery::ViewSamples;

bool finite_row(const Vec3<double>& wo, double pdf, const double* weight, int channels) {
  bool ok = wo.allFinite() && std::isfinite(pdf);
  for (int c = 0; c < channels; ++c) ok = ok && std::isfinite(weight[c]);
  return ok;
}

// n samples from wi: uniforms of sample i from CounterRng(seed, i), as the command line's dumps draw them.
Samples draw(const BsdfUnderTest& b, const Vec3<double>& wi, const BatteryOptions& o) {
  Samples s;
  s.drawn = o.samples;
  const std::size_t c = std::size_t(b.channels);
  for (std::uint64_t first = 0; first < o.samples; first += kBatch) {
    if (o.run.cancelled()) throw Cancelled("the BSDF's samples");
    const std::size_t n = std::size_t(std::min<std::uint64_t>(kBatch, o.samples - first));
    std::vector<Vec3<double>> in(n, wi), wo(n);
    std::vector<double> u(3 * n), pdf(n), weight(c * n);
    std::vector<unsigned char> kept(n);
    for (std::size_t i = 0; i < n; ++i) {
      CounterRng rng(o.seed, first + i);
      for (int k = 0; k < 3; ++k) u[3 * i + std::size_t(k)] = rng.uniform();
    }
    b.sample(in, u, wo, pdf, weight, kept);
    for (std::size_t i = 0; i < n; ++i) {
      if (!kept[i]) {
        ++s.lost;
        continue;
      }
      if (!finite_row(wo[i], pdf[i], &weight[c * i], b.channels)) ++s.non_finite;
      s.wo.push_back(wo[i]);
      s.pdf.push_back(pdf[i]);
      s.weight.insert(s.weight.end(), weight.begin() + std::ptrdiff_t(c * i), weight.begin() + std::ptrdiff_t(c * (i + 1)));
    }
  }
  return s;
}

// The samples as an array in memory: columns x, y, z, pdf, weight per channel.
DirectionSampleReader sample_reader(const Samples& s, int channels) {
  SampleArray a;
  a.name = "the BSDF's samples";
  a.rows = s.wo.size();
  for (int k = 0; k < 3; ++k) a.columns.push_back({&s.wo.front()[k], std::ptrdiff_t(sizeof(Vec3<double>)), false});
  a.columns.push_back({s.pdf.data(), std::ptrdiff_t(sizeof(double)), false});
  for (int c = 0; c < channels; ++c) a.columns.push_back({s.weight.data() + c, std::ptrdiff_t(sizeof(double)) * channels, false});
  std::string spec = "x,y,z,pdf";
  for (int c = 0; c < channels; ++c) spec += ",weight";
  return DirectionSampleReader(std::move(a), SampleColumns::parse(spec));
}

// Each sample's weight against eval / pdf, and its pdf against pdf(), at the sampled direction.
BatteryLine consistency(const BsdfUnderTest& b, const Vec3<double>& wi, const Samples& s, const std::string& view) {
  const std::size_t n = s.wo.size(), c = std::size_t(b.channels);
  std::vector<Vec3<double>> in(n, wi);
  std::vector<double> value(c * n), pdf(n);
  b.eval(in, s.wo, value);
  b.pdf(in, s.wo, pdf);
  std::uint64_t bad = 0;
  std::string first;
  for (std::size_t i = 0; i < n; ++i) {
    bool ok = std::abs(pdf[i] - s.pdf[i]) <= kConsistency * std::abs(s.pdf[i]) + 1e-300;
    for (std::size_t k = 0; k < c; ++k)
      ok = ok && std::abs(s.weight[c * i + k] - value[c * i + k] / pdf[i]) <= kConsistency * std::abs(s.weight[c * i + k]) + 1e-300;
    if (!ok && bad++ == 0)
      first = fmt::format("e.g. wo ({:.4f}, {:.4f}, {:.4f}): weight {:.6g}, eval / pdf {:.6g}, pdf {:.6g} vs pdf() {:.6g}",
                          s.wo[i].x(), s.wo[i].y(), s.wo[i].z(), s.weight[c * i], value[c * i] / pdf[i], s.pdf[i], pdf[i]);
  }
  return {"consistency", view,
          bad == 0 ? "weights = eval / pdf and pdfs = pdf() at every sample"
                   : fmt::format("{} of {} samples disagree; {}", bad, n, first),
          -1, bad == 0};
}

// The statistical tests of one view's samples under `o.reference`, each at `level`.
int view_tests(const BsdfUnderTest& b, const BatteryOptions& o) {
  return (o.reference != BatteryReference::none ? 1 : 0) + (b.pdf ? 1 : 0) + 2;
}

// The sampling validation against the exact single scattering (validate/dump_validation.h).
BatteryLine sampling_against_exact(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx,
                                   const Vec3<double>& wi, const Samples& s, const std::string& view,
                                   const BatteryOptions& o, double level) {
  DirectionSampleReader reader = sample_reader(s, b.channels);
  ValidationOptions v;
  v.significance = level;
  v.bsdf = m;
  v.convention = b.convention;
  v.dropped_below_horizon = s.lost;
  v.run = o.run;
  const ValidationReport r = validate_dump_as_given(reader, {FilePdf::bsdf, m, true}, ggx, wi, v, false);
  return {"sampling", view, r.passed ? fmt::format("{} samples, {} lost", s.wo.size(), s.lost) : r.failures.front(),
          r.p_value, r.passed};
}

// One view: its sampling against the reference, its tests against itself, and (a deterministic eval() with a
// pdf()) the samples' pointwise consistency.
void check_view(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx, const BatteryView& v,
                const BatteryOptions& o, double level, BatteryReport& report) {
  std::vector<BatteryLine>& lines = report.lines;
  const std::string view = view_label(v);
  const Vec3<double> wi = direction_from_degrees(v.theta, v.phi);
  const Samples s = draw(b, wi, o);
  if (s.non_finite > 0) lines.push_back({"finite", view, fmt::format("{} samples with a non-finite value", s.non_finite), -1, false});
  if (s.wo.empty()) {
    lines.push_back({"sampling", view, "every sample was lost", -1, false});
    return;
  }
  if (o.reference == BatteryReference::single_scattering)
    lines.push_back(sampling_against_exact(b, m, ggx, wi, s, view, o, level));
  if (o.reference == BatteryReference::smith_walk)
    lines.push_back(battery::sampling_against_walk(b, m, ggx, wi, s, view, level, o));
  for (BatteryLine& l : battery::self_tests(b, wi, s, view, level, o, report.residuals)) lines.push_back(std::move(l));
  if (!b.stochastic_eval && b.pdf) lines.push_back(consistency(b, wi, s, view));
}

using battery::reciprocal_ratio;

// The BSDF's own reciprocity at the query pairs off the horizon where it is not negligible: eval at (wo, wi)
// against eval at (wi, wo) times the ratio above, within 1e-3 relative (no reference needed: it holds for a
// multiple-scattering BSDF too).
BatteryLine reciprocity(const BsdfUnderTest& b, const Material& m, const std::vector<BsdfQuery>& q,
                        const std::vector<double>& values) {
  std::vector<Vec3<double>> wi, wo;
  for (const BsdfQuery& x : q) wi.push_back(x.wo), wo.push_back(x.wi);
  std::vector<double> swapped(values.size());
  b.eval(wi, wo, swapped);
  const std::size_t c = std::size_t(b.channels);
  double largest = 0;
  for (const double v : values) largest = std::max(largest, std::abs(v));
  std::uint64_t checked = 0, bad = 0;
  std::string first;
  for (std::size_t i = 0; i < q.size(); ++i) {
    const double ci = std::abs(q[i].wi.z()), co = std::abs(q[i].wo.z());
    if (ci < 1e-3 || co < 1e-3) continue;
    for (std::size_t k = 0; k < c; ++k) {
      const double f_io = values[c * i + k] / co, f_oi = swapped[c * i + k] / ci;
      if (std::max(std::abs(f_io), std::abs(f_oi)) < 1e-9 * largest) continue;
      ++checked;
      const double expected = f_io * reciprocal_ratio(m, b.convention, q[i].wi, q[i].wo);
      if (std::abs(f_oi - expected) <= kConsistency * std::max(std::abs(f_oi), std::abs(expected))) continue;
      if (bad++ == 0)
        first = fmt::format("e.g. f(wo, wi) {:.6g} where reciprocity gives {:.6g}, wi ({:.3f}, {:.3f}, {:.3f}), wo ({:.3f}, "
                            "{:.3f}, {:.3f})", f_oi, expected, q[i].wi.x(), q[i].wi.y(), q[i].wi.z(), q[i].wo.x(),
                            q[i].wo.y(), q[i].wo.z());
    }
  }
  return {"reciprocity", "bsdf-queries",
          bad == 0 ? fmt::format("{} pairs: f(wo, wi) as reciprocity gives ({})", checked, describe(b.convention))
                   : fmt::format("{} of {} pairs break reciprocity in {}; {}", bad, checked, describe(b.convention), first),
          -1, bad == 0};
}

// eval() and pdf() at the query pairs.
BatteryLine check_eval(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx, const BatteryOptions& o,
                       EvalCheckReport& report, BatteryLine& reciprocity_line) {
  const std::vector<BsdfQuery> q = bsdf_queries(m, 256, o.seed, ggx);
  std::vector<Vec3<double>> wi, wo;
  for (const BsdfQuery& x : q) wi.push_back(x.wi), wo.push_back(x.wo);
  std::vector<double> values(q.size() * std::size_t(b.channels)), pdfs(q.size());
  b.eval(wi, wo, values);
  b.pdf(wi, wo, pdfs);
  EvalCheckOptions e;
  e.convention = b.convention;
  e.arithmetic = o.arithmetic;
  e.run = o.run;
  report = check_eval_values(q, values, pdfs, m, ggx, e, b.name);
  reciprocity_line = reciprocity(b, m, q, values);
  std::string detail = fmt::format("{} pairs: {} values, {} pdfs outside their tolerance", q.size(), report.value_failures,
                                   report.pdf_failures);
  if (!report.passed && !report.worst.empty()) {
    const EvalMismatch& w = report.worst.front();
    detail += fmt::format("; worst: {} {:.6g} against {:.6g} at wi ({:.3f}, {:.3f}, {:.3f}), wo ({:.3f}, {:.3f}, {:.3f})",
                          w.quantity, w.given, w.reference, w.wi.x(), w.wi.y(), w.wi.z(), w.wo.x(), w.wo.y(), w.wo.z());
  }
  return {"eval", "bsdf-queries", detail, -1, report.passed};
}

// The eval and reciprocity lines of a BSDF without an exact reference (or with a stochastic eval()).
void check_eval_stochastic(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx, const BatteryOptions& o,
                           double level, std::vector<BatteryLine>& lines) {
  const std::vector<BsdfQuery> q = bsdf_queries(m, 256, o.seed, ggx);
  const std::vector<BsdfQuery> pairs = battery::stochastic_pairs(q, o.stochastic_pairs);
  if (o.reference == BatteryReference::smith_walk) lines.push_back(battery::eval_against_walk(b, m, ggx, pairs, level, o));
  if (b.stochastic_eval) {
    lines.push_back(battery::stochastic_reciprocity(b, m, pairs, level, o));
    return;
  }
  std::vector<Vec3<double>> wi, wo;
  for (const BsdfQuery& x : q) wi.push_back(x.wi), wo.push_back(x.wo);
  std::vector<double> values(q.size() * std::size_t(b.channels));
  b.eval(wi, wo, values);
  lines.push_back(reciprocity(b, m, q, values));
}

void check_views(const Material& m, const std::vector<BatteryView>& views) {
  for (const BatteryView& v : views) {
    if (!(v.theta >= 0 && v.theta <= 180 && v.theta != 90 && std::isfinite(v.phi)))
      throw std::invalid_argument(fmt::format("view theta {} phi {}: theta in [0, 180] and not 90 deg", v.theta, v.phi));
    if (v.theta > 90 && !m.transmits())
      throw std::invalid_argument(fmt::format("view theta {}: from inside, only a dielectric", v.theta));
  }
}

}  // namespace

std::vector<BatteryView> battery_views(const Material& m, const GGX<double>& ggx, SampledNormals normals) {
  std::vector<double> thetas{0, 30, 60, 80, 89.9}, turned{60, 80};
  if (normals == SampledNormals::ndf) thetas.pop_back();
  if (m.transmits()) thetas.insert(thetas.end(), {120, 150}), turned.push_back(120);
  std::vector<BatteryView> v;
  for (const double t : thetas) v.push_back({t, 0});
  if (ggx.alpha_x() != ggx.alpha_y())
    for (const double t : turned)
      for (const double phi : {30.0, 60.0}) v.push_back({t, phi});
  return v;
}

std::string battery_refusal(const Material& claimed, SampledNormals normals) {
  if (!claimed.transmits() || normals != SampledNormals::ndf) return "";
  return "a dielectric sampling its normals from D(m) cos has heavy-tailed weights (~ 1 / m.z near the horizon), which "
         "the battery's weight tests cannot judge: test its directions and pdfs with `microsim validate --from DUMP "
         "--sampling ndf` (its weight columns left out) and its eval() with check-eval";
}

std::string view_label(const BatteryView& v) {
  return v.phi == 0 ? fmt::format("{:g} deg", v.theta) : fmt::format("{:g} deg phi {:g}", v.theta, v.phi);
}

BatteryReport run_bsdf_battery(const BsdfUnderTest& bsdf, const Material& claimed, const GGX<double>& ggx,
                               const BatteryOptions& options) {
  if (claimed.kind() == MaterialKind::lambertian) throw std::invalid_argument("the battery needs a mirror, a conductor or a dielectric");
  if (bsdf.channels != claimed.channels())
    throw std::invalid_argument(fmt::format("the BSDF has {} channel(s), the claimed {} has {}", bsdf.channels,
                                            claimed.describe(), claimed.channels()));
  const bool exact = options.reference == BatteryReference::single_scattering;
  if (exact && (bsdf.stochastic_eval || !bsdf.pdf))
    throw std::invalid_argument("the exact single-scattering reference needs a deterministic eval() and a pdf()");
  if (const std::string why = battery_refusal(claimed, bsdf.convention.normals); !why.empty())
    throw std::invalid_argument(why);
  const std::vector<BatteryView> views = options.views.empty() ? battery_views(claimed, ggx, bsdf.convention.normals) : options.views;
  check_views(claimed, views);
  const int statistical = int(views.size()) * view_tests(bsdf, options) +
                          (options.reference == BatteryReference::smith_walk ? 1 : 0) + (bsdf.stochastic_eval ? 1 : 0);
  const double level = sidak_significance(options.level, statistical);
  BatteryReport r;
  r.convention = describe(bsdf.convention);
  for (const BatteryView& v : views) check_view(bsdf, claimed, ggx, v, options, level, r);
  if (exact) {
    BatteryLine reciprocal;
    r.lines.push_back(check_eval(bsdf, claimed, ggx, options, r.eval, reciprocal));
    r.lines.push_back(std::move(reciprocal));
  } else {
    check_eval_stochastic(bsdf, claimed, ggx, options, level, r.lines);
  }
  r.passed = true;
  for (const BatteryLine& l : r.lines) r.passed = r.passed && l.passed;
  return r;
}

nlohmann::json to_json(const BatteryReport& r) {
  nlohmann::json tests = nlohmann::json::array();
  for (const BatteryLine& l : r.lines)
    tests.push_back({{"test", l.test}, {"view", l.view}, {"p", l.p < 0 ? nlohmann::json(nullptr) : nlohmann::json(l.p)},
                     {"passed", l.passed}, {"tested", l.tested}, {"detail", l.detail}});
  // The pointwise eval check runs against an exact reference only (null otherwise).
  const bool eval_checked = r.eval.rows > 0;
  return {{"verdict", r.passed ? "pass" : "fail"}, {"convention", r.convention}, {"tests", tests}, {"eval", eval_checked ? to_json(r.eval) : nlohmann::json(nullptr)}};
}

}  // namespace microsim
