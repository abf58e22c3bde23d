// microsim check-bsdf --plugin LIB.so: a renderer's BSDF, loaded in process through the C interface of
// include/microsim/bsdf_plugin.h, tested against the exact single-scattering BSDF it claims (--bsdf, --alpha):
//   - per view (0, 30, 60, 80 and 89.9 deg; 120 and 150 deg from inside a dielectric): its samples' directions
//     against its sampling density, their returned pdfs, and their weights against the BSDF in its transport
//     mode (validate/dump_validation.h, the lost samples dropped and counted as a renderer drops them);
//   - its eval() and pdf() at the pairs of bsdf-queries, pointwise (validate/eval_check.h);
//   - its consistency with itself: each sample's weight against eval / pdf at the sampled direction, and its
//     returned pdf against pdf(), within 1e-3 relative;
//   - non-finite outputs anywhere, including the grazing views: a failure.
// The statistical tests share the family-wise level (Sidak over the views); exit 0 every test passed, 1 one
// rejected, 2 bad usage or a plugin that cannot be loaded, 130 interrupted.
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "microsim/bsdf_plugin.h"
#include "core/atomic_file.h"
#include "core/random.h"
#include "microfacet/roughness.h"
#include "stats/chi2.h"
#include "validate/bsdf_queries.h"
#include "validate/dump_validation.h"
#include "validate/eval_check.h"

#include <dlfcn.h>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct CheckArgs {
  std::string plugin, bsdf, alpha, json, arithmetic = "float32";
  std::vector<std::string> params;
  long long samples = 200'000;
  unsigned long long seed = 1;
  double level = 0.01;
};

// The loaded library and one BSDF it created; both released in reverse order.
class LoadedPlugin {
public:
  LoadedPlugin(const std::string& path, const std::string& params) {
    library_ = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!library_) throw UsageError(fmt::format("--plugin '{}': {}", path, dlerror()));
    const auto entry = reinterpret_cast<microsim_bsdf_plugin_entry_fn>(dlsym(library_, "microsim_bsdf_plugin_entry"));
    if (!entry) throw UsageError(fmt::format("--plugin '{}': no microsim_bsdf_plugin_entry", path));
    api_ = entry();
    if (!api_ || api_->abi_version != MICROSIM_BSDF_PLUGIN_ABI)
      throw UsageError(fmt::format("--plugin '{}': not of ABI version {}", path, MICROSIM_BSDF_PLUGIN_ABI));
    if (api_->channels < 1 || api_->channels > MICROSIM_BSDF_MAX_CHANNELS)
      throw UsageError(fmt::format("--plugin '{}': {} channels", path, api_->channels));
    self_ = api_->create(params.c_str());
    if (!self_) throw UsageError(fmt::format("--plugin '{}': create(\"{}\") refused the parameters", path, params));
  }
  ~LoadedPlugin() {
    if (self_) api_->destroy(self_);
    if (library_) dlclose(library_);
  }
  LoadedPlugin(const LoadedPlugin&) = delete;
  LoadedPlugin& operator=(const LoadedPlugin&) = delete;
  const microsim_bsdf_plugin& api() const { return *api_; }
  void* self() const { return self_; }

private:
  void* library_ = nullptr;
  const microsim_bsdf_plugin* api_ = nullptr;
  void* self_ = nullptr;
};

// One test's line of the table.
struct TestLine {
  std::string test, view, detail;
  double p = NAN;  // statistical tests
  bool passed = true;
};

struct Samples {
  std::vector<Vec3<double>> wo;
  std::vector<double> pdf, weight;  // weight: channels per row
  std::uint64_t lost = 0, non_finite = 0;
};

Samples draw(const LoadedPlugin& p, const Vec3<double>& wi, std::uint64_t n, std::uint64_t seed, const RunControl& run) {
  Samples s;
  const int channels = p.api().channels;
  double w[3], pdf = 0, weight[MICROSIM_BSDF_MAX_CHANNELS];
  const double in[3] = {wi.x(), wi.y(), wi.z()};
  for (std::uint64_t i = 0; i < n; ++i) {
    if (i % 65536 == 0 && run.cancelled()) throw Cancelled("check-bsdf: sampling");
    CounterRng rng(seed, i);
    const double u[3] = {rng.uniform(), rng.uniform(), rng.uniform()};
    if (!p.api().sample(p.self(), in, u, w, &pdf, weight)) {
      ++s.lost;
      continue;
    }
    bool finite = std::isfinite(w[0]) && std::isfinite(w[1]) && std::isfinite(w[2]) && std::isfinite(pdf);
    for (int c = 0; c < channels; ++c) finite = finite && std::isfinite(weight[c]);
    if (!finite) ++s.non_finite;
    s.wo.emplace_back(w[0], w[1], w[2]);
    s.pdf.push_back(pdf);
    s.weight.insert(s.weight.end(), weight, weight + channels);
  }
  return s;
}

// The samples as an array in memory: columns x, y, z, pdf, weight per channel.
DirectionSampleReader sample_reader(const Samples& s, int channels) {
  SampleArray a;
  a.name = "the plugin's samples";
  a.rows = s.wo.size();
  for (int k = 0; k < 3; ++k) a.columns.push_back({&s.wo.front()[k], std::ptrdiff_t(sizeof(Vec3<double>)), false});
  a.columns.push_back({s.pdf.data(), std::ptrdiff_t(sizeof(double)), false});
  for (int c = 0; c < channels; ++c)
    a.columns.push_back({s.weight.data() + c, std::ptrdiff_t(sizeof(double)) * channels, false});
  std::string spec = "x,y,z,pdf";
  for (int c = 0; c < channels; ++c) spec += ",weight";
  return DirectionSampleReader(std::move(a), SampleColumns::parse(spec));
}

// Each sample's weight against eval / pdf, and its pdf against pdf(), at the sampled direction.
TestLine consistency(const LoadedPlugin& p, const Vec3<double>& wi, const Samples& s, const std::string& view) {
  const int channels = p.api().channels;
  const double in[3] = {wi.x(), wi.y(), wi.z()};
  std::uint64_t bad = 0;
  std::string first;
  for (std::size_t i = 0; i < s.wo.size(); ++i) {
    const double out[3] = {s.wo[i].x(), s.wo[i].y(), s.wo[i].z()};
    double value[MICROSIM_BSDF_MAX_CHANNELS];
    p.api().eval(p.self(), in, out, value);
    const double pdf = p.api().pdf(p.self(), in, out);
    bool ok = std::abs(pdf - s.pdf[i]) <= 1e-3 * std::abs(s.pdf[i]) + 1e-300;
    for (int c = 0; c < channels; ++c) {
      const double w = s.weight[i * std::size_t(channels) + std::size_t(c)], expected = value[c] / pdf;
      ok = ok && std::abs(w - expected) <= 1e-3 * std::abs(w) + 1e-300;
    }
    if (!ok && bad++ == 0)
      first = fmt::format("e.g. wo ({:.4f}, {:.4f}, {:.4f}): weight {:.6g}, eval / pdf {:.6g}, pdf {:.6g} vs pdf() {:.6g}",
                          out[0], out[1], out[2], s.weight[i * std::size_t(channels)], value[0] / pdf, s.pdf[i], pdf);
  }
  return {"consistency", view, bad == 0 ? "weights = eval / pdf and pdfs = pdf() at every sample"
                                        : fmt::format("{} of {} samples disagree; {}", bad, s.wo.size(), first),
          NAN, bad == 0};
}

std::vector<double> view_thetas(const Material& m) {
  std::vector<double> v{0, 30, 60, 80, 89.9};
  if (m.transmits()) v.insert(v.end(), {120, 150});
  return v;
}

Vec3<double> view_of(double theta) {
  const double t = theta * kPi<double> / 180;
  return {std::sin(t), 0, std::cos(t)};
}

// The sampling validation of one view (level: its Sidak share), and the samples' consistency.
void check_view(const LoadedPlugin& p, const Material& m, const GGX<double>& ggx, double theta, const CheckArgs& a,
                double level, const RunControl& run, std::vector<TestLine>& lines) {
  const std::string view = fmt::format("{:g} deg", theta);
  const Vec3<double> wi = view_of(theta);
  const Samples s = draw(p, wi, std::uint64_t(a.samples), a.seed, run);
  if (s.non_finite > 0) lines.push_back({"finite", view, fmt::format("{} samples with a non-finite value", s.non_finite), NAN, false});
  DirectionSampleReader reader = sample_reader(s, p.api().channels);
  ValidationOptions o;
  o.significance = level;
  o.bsdf = m;
  o.convention = {p.api().transport == 1 ? TransportMode::importance : TransportMode::radiance,
                  p.api().masking == 1 ? MaskingForm::separable : MaskingForm::height_correlated};
  o.dropped_below_horizon = s.lost;
  o.run = run;
  const ValidationReport r = validate_dump_as_given(reader, {FilePdf::bsdf, m, true}, ggx, wi, o, false);
  lines.push_back({"sampling", view,
                   r.passed ? fmt::format("{} samples, {} lost", s.wo.size(), s.lost) : r.failures.front(), r.p_value,
                   r.passed});
  lines.push_back(consistency(p, wi, s, view));
}

// eval() and pdf() at the query pairs, and non-finite values at the grazing and degenerate pairs among them.
TestLine check_eval(const LoadedPlugin& p, const Material& m, const GGX<double>& ggx, const CheckArgs& a, const RunControl& run,
                    EvalCheckReport& report) {
  const std::vector<BsdfQuery> q = bsdf_queries(m, 256, a.seed, ggx);
  const int channels = p.api().channels;
  std::vector<double> values(q.size() * std::size_t(channels)), pdfs(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    const double wi[3] = {q[i].wi.x(), q[i].wi.y(), q[i].wi.z()}, wo[3] = {q[i].wo.x(), q[i].wo.y(), q[i].wo.z()};
    p.api().eval(p.self(), wi, wo, &values[i * std::size_t(channels)]);
    pdfs[i] = p.api().pdf(p.self(), wi, wo);
  }
  EvalCheckOptions o;
  o.convention = {p.api().transport == 1 ? TransportMode::importance : TransportMode::radiance,
                  p.api().masking == 1 ? MaskingForm::separable : MaskingForm::height_correlated};
  o.arithmetic = a.arithmetic == "float64" ? Precision::float64 : Precision::float32;
  o.run = run;
  report = check_eval_values(q, values, pdfs, m, ggx, o, p.api().name);
  std::string detail = fmt::format("{} pairs: {} values, {} pdfs outside their tolerance", q.size(), report.value_failures,
                                   report.pdf_failures);
  if (!report.worst.empty() && !report.passed)
    detail += fmt::format("; worst: {} {:.6g} against {:.6g} at wi ({:.3f}, {:.3f}, {:.3f}), wo ({:.3f}, {:.3f}, {:.3f})",
                          report.worst[0].quantity, report.worst[0].given, report.worst[0].reference, report.worst[0].wi.x(),
                          report.worst[0].wi.y(), report.worst[0].wi.z(), report.worst[0].wo.x(), report.worst[0].wo.y(),
                          report.worst[0].wo.z());
  return {"eval", "bsdf-queries", detail, NAN, report.passed};
}

void print_table(const std::vector<TestLine>& lines, bool passed) {
  fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", "test", "view", "p", "verdict", "detail");
  for (const TestLine& l : lines)
    fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", l.test, l.view, std::isnan(l.p) ? "-" : fmt::format("{:.3g}", l.p),
               l.passed ? "pass" : "REJECTED", l.detail);
  fmt::print("{}\n", passed ? "passed" : "REJECTED");
}

nlohmann::json report_json(const CheckArgs& a, const std::vector<TestLine>& lines, const EvalCheckReport& eval, bool passed) {
  nlohmann::json tests = nlohmann::json::array();
  for (const TestLine& l : lines)
    tests.push_back({{"test", l.test}, {"view", l.view}, {"p", std::isnan(l.p) ? nlohmann::json(nullptr) : nlohmann::json(l.p)},
                     {"passed", l.passed}, {"detail", l.detail}});
  return {{"verdict", passed ? "pass" : "fail"}, {"plugin", a.plugin}, {"bsdf", a.bsdf}, {"alpha", a.alpha},
          {"level", a.level}, {"tests", tests}, {"eval", to_json(eval)}};
}

int run_check_bsdf(const CheckArgs& a) {
  check_distinct_outputs({{"--plugin", a.plugin}}, {{"--json", a.json}});
  check_output("--json", a.json);
  if (a.arithmetic != "float32" && a.arithmetic != "float64")
    throw UsageError(fmt::format("--arithmetic {}: float32 or float64", quote_excerpt(a.arithmetic)));
  const Material m = parse_material("--bsdf", a.bsdf);
  if (m.kind() == MaterialKind::lambertian) throw UsageError("--bsdf: mirror, conductor:ETA,K or dielectric:ETA");
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const GGX<double> ggx(ax, ay);
  std::string params;
  for (const std::string& p : a.params) params += (params.empty() ? "" : " ") + p;
  const LoadedPlugin plugin(a.plugin, params);
  if (plugin.api().channels != m.channels())
    throw UsageError(fmt::format("--plugin has {} channel(s), --bsdf {} has {}", plugin.api().channels, a.bsdf, m.channels()));
  install_interrupt_handler();
  const RunControl run = cli_run_control(0, nullptr);
  const std::vector<double> thetas = view_thetas(m);
  const double level = sidak_significance(a.level, int(thetas.size()));
  std::vector<TestLine> lines;
  EvalCheckReport eval;
  try {
    for (const double theta : thetas) check_view(plugin, m, ggx, theta, a, level, run, lines);
    lines.push_back(check_eval(plugin, m, ggx, a, run, eval));
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-bsdf");
  }
  bool passed = true;
  for (const TestLine& l : lines) passed = passed && l.passed;
  if (!a.json.empty()) write_file_atomically(a.json, report_json(a, lines, eval, passed).dump(2) + "\n");
  print_table(lines, passed);
  return passed ? kExitOk : kExitRejected;
}

CommandRegistration check_bsdf_registration{"check-bsdf", [](CLI::App& app) {
  auto a = std::make_shared<CheckArgs>();
  auto* sub = app.add_subcommand(
      "check-bsdf",
      "Test a renderer's BSDF in process through the C plugin interface (include/microsim/bsdf_plugin.h) against the "
      "exact single-scattering BSDF it claims: its samples per view (directions, returned pdfs, weights), its eval() "
      "and pdf() at the pairs of bsdf-queries, its weights against eval / pdf, non-finite values. Exit 0 passed, 1 "
      "rejected, 2 bad usage or a plugin that cannot be loaded.");
  sub->add_option("--plugin", a->plugin, "the shared library (.so) defining microsim_bsdf_plugin_entry")->required();
  sub->add_option("--param", a->params, "a key=value parameter passed to the plugin's create() (repeatable)");
  sub->add_option("--bsdf", a->bsdf, "the BSDF it claims: mirror, conductor:ETA,K or dielectric:ETA")->required();
  sub->add_option("--alpha", a->alpha, "its GGX roughness AX or AX,AY")->required();
  add_number_option(sub, "--samples", a->samples, whole(1000, 100'000'000), "samples per view")->default_str("200000");
  add_number_option(sub, "--seed", a->seed, whole(), "seed of the uniforms")->default_str("1");
  add_number_option(sub, "--level", a->level, real(), "family-wise significance level (Sidak over the views)")->default_str("0.01");
  sub->add_option("--arithmetic", a->arithmetic, "the plugin's arithmetic for the eval tolerances: float32 or float64")
      ->capture_default_str();
  sub->add_option("--json", a->json, "write the report as JSON");
  on_selected(sub, [a] { return run_check_bsdf(*a); });
}};

}  // namespace
}  // namespace microsim::app
