// microsim check-eval FILE: a renderer's eval() (and pdf()) at given pairs (wi, wo) against the exact
// single-scattering BSDF, pointwise with a tolerance from the file's precision and the reference's
// conditioning (validate/eval_check.h); with --model smith-walk, its values against the Smith walk's
// next-event estimate by a chi-square over pairs (measure/walk_eval_check.h). microsim bsdf-queries writes a
// query set to fill in.
//
// Exit codes: 0 every value within its tolerance, 1 a value or pdf outside (the worst named), 2 bad usage or
// input, 130 interrupted (nothing written).
#include "bsdf_options.h"
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "microfacet/roughness.h"
#include "measure/walk_eval_check.h"
#include "validate/eval_check.h"

#include <fmt/core.h>

#include <memory>
#include <string>

namespace microsim::app {
namespace {

struct EvalArgs {
  std::string file, alpha, bsdf, columns = "wi,wo,value", transport, masking, sampling, frame = "z-up",
      arithmetic = "float32", json;
  std::string model = "exact";
  int worst = 10;
  long long paths = 32768;
  unsigned long long seed = 1;
  double level = 0.01;
};

EvalCheckOptions options_of(const EvalArgs& a) {
  EvalCheckOptions o;
  try {
    if (!a.transport.empty()) o.convention.transport = parse_transport_mode("--transport", a.transport);
    if (!a.masking.empty()) o.convention.masking = parse_masking_form("--masking", a.masking);
    if (!a.sampling.empty()) o.convention.normals = parse_sampled_normals("--sampling", a.sampling);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (a.frame != "z-up" && a.frame != "y-up") throw UsageError(fmt::format("--frame {}: z-up or y-up", quote_excerpt(a.frame)));
  o.frame = a.frame == "y-up" ? SampleFrame::y_up : SampleFrame::z_up;
  o.arithmetic = arithmetic_option(a.arithmetic);
  o.worst = std::size_t(a.worst);
  return o;
}

void print_report(const EvalCheckReport& r) {
  fmt::print("check-eval {}: {} rows ({}); {} values and {} pdfs checked\n", r.file, r.rows, r.storage, r.values_checked,
             r.pdfs_checked);
  fmt::print("outside their tolerance: {} values, {} pdfs; the tightest tolerances up to {:.3g} relative\n",
             r.value_failures, r.pdf_failures, r.max_relative_tolerance_tight);
  if (!r.worst.empty())
    fmt::print("{:>9} {:<10} {:>28} {:>28} {:>13} {:>13} {:>10} {:>9}\n", "row", "quantity", "wi", "wo", "given",
               "reference", "tolerance", "excess");
  for (const EvalMismatch& m : r.worst)
    fmt::print("{:>9} {:<10} {:>28} {:>28} {:>13.6g} {:>13.6g} {:>10.3g} {:>9.3g}\n", m.row, m.quantity,
               fmt::format("({:.4f}, {:.4f}, {:.4f})", m.wi.x(), m.wi.y(), m.wi.z()),
               fmt::format("({:.4f}, {:.4f}, {:.4f})", m.wo.x(), m.wo.y(), m.wo.z()), m.given, m.reference, m.tolerance,
               m.excess());
  for (const std::string& n : r.notes) fmt::print("note: {}\n", n);
  fmt::print("{}\n", r.passed ? "passed" : "REJECTED");
}

void print_walk_report(const WalkEvalCheckReport& r) {
  fmt::print("check-eval {} against the Smith walk: {} rows ({}), {} skipped at the horizon\n", r.file, r.rows, r.storage,
             r.skipped);
  fmt::print("chi2 {:.6g} over {} terms, p {:.3g}\n", r.statistic, r.dof, r.p_value);
  if (!r.worst.empty())
    fmt::print("{:>9} {:>3} {:>28} {:>28} {:>13} {:>13} {:>10} {:>8}\n", "row", "ch", "wi", "wo", "given", "walk", "walk se", "z");
  for (const WalkEvalPair& m : r.worst)
    fmt::print("{:>9} {:>3} {:>28} {:>28} {:>13.6g} {:>13.6g} {:>10.3g} {:>8.3g}\n", m.row, m.channel,
               fmt::format("({:.4f}, {:.4f}, {:.4f})", m.wi.x(), m.wi.y(), m.wi.z()),
               fmt::format("({:.4f}, {:.4f}, {:.4f})", m.wo.x(), m.wo.y(), m.wo.z()), m.given, m.walk.value,
               m.walk.standard_error, m.z);
  fmt::print("{}\n", r.passed ? "passed" : "REJECTED");
}

int run_walk_check(const EvalArgs& a, const EvalColumns& columns, const Material& bsdf, double ax, double ay) {
  const EvalCheckOptions e = options_of(a);
  WalkEvalCheckOptions o;
  o.convention = e.convention, o.frame = e.frame, o.paths = std::uint64_t(a.paths), o.seed = a.seed;
  o.level = a.level, o.worst = std::size_t(a.worst);
  SmithMicrosurface surface;
  surface.alpha_x = ax, surface.alpha_y = ay;
  install_interrupt_handler();
  o.run = cli_run_control(0, nullptr);
  WalkEvalCheckReport r;
  try {
    r = check_eval_file_against_walk(a.file, columns, bsdf, surface, o);
  } catch (const SampleFileError& err) {
    throw UsageError(err.what());
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-eval");
  }
  if (!a.json.empty()) write_file_atomically(a.json, to_json(r).dump(2) + "\n");
  print_walk_report(r);
  return r.passed ? kExitOk : kExitRejected;
}

int run_check_eval(const EvalArgs& a) {
  check_distinct_outputs({{"FILE", a.file}}, {{"--json", a.json}});
  check_output("--json", a.json);
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const Material bsdf = microfacet_bsdf_option(a.bsdf);
  EvalColumns columns;
  try {
    columns = EvalColumns::parse(a.columns);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--columns: {}", e.what()));
  }
  if (!a.sampling.empty() && (a.model == "smith-walk" || !columns.has_pdf()))
    throw UsageError("--sampling says what the pdf column is the density of: it applies to --model exact with a pdf "
                     "column (--columns wi,wo,value,pdf)");
  if (a.model == "smith-walk") return run_walk_check(a, columns, bsdf, ax, ay);
  if (a.model != "exact") throw UsageError(fmt::format("--model {}: exact or smith-walk", quote_excerpt(a.model)));
  EvalCheckOptions o = options_of(a);
  install_interrupt_handler();
  o.run = cli_run_control(1, nullptr);
  EvalCheckReport r;
  try {
    r = check_eval_file(a.file, columns, bsdf, GGX<double>(ax, ay), o);
  } catch (const SampleFileError& e) {
    throw UsageError(e.what());
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-eval");
  }
  if (!a.json.empty()) write_file_atomically(a.json, to_json(r).dump(2) + "\n");
  print_report(r);
  return r.passed ? kExitOk : kExitRejected;
}

CommandRegistration check_eval_registration{"check-eval", [](CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  auto* sub = app.add_subcommand(
      "check-eval",
      "Check a renderer's eval() and pdf() at given pairs (wi, wo) against the exact single-scattering BSDF, pointwise, "
      "each value within a tolerance from the file's precision and the BSDF's conditioning; the worst pairs are named. "
      "With --model smith-walk, against the Smith multiple-scattering BSDF (Heitz et al. 2016): per pair the walk's "
      "next-event estimate with its standard error, a chi-square over the pairs at --level, the worst pairs named. "
      "`microsim bsdf-queries` writes a query set to fill in. Exit 0 passed, 1 rejected, 2 bad usage or input.");
  sub->add_option("file", a->file,
                  "eval file: .npy (any layout numpy writes, float32 or float64) or text, one row per pair: wi (the "
                  "direction the renderer was given), wo, f(wi, wo) |cos wo| per channel of the BSDF, [pdf(wo | wi)]")
      ->required();
  sub->add_option("--alpha", a->alpha, "GGX roughness AX or AX,AY of the BSDF")->required();
  sub->add_option("--bsdf", a->bsdf, "the BSDF: mirror, conductor:ETA,K[;ETA,K...] (one pair per channel) or dielectric:ETA")
      ->required();
  sub->add_option("--columns", a->columns,
                  "what a row holds, in order: wi, wo, value (one column per channel), pdf, - (a column to skip)")
      ->capture_default_str();
  sub->add_option("--transport", a->transport,
                  "a dielectric's transport mode: radiance (default: camera paths; a refraction's f holds (n_given / "
                  "n_sampled)^2) or importance (light paths)");
  sub->add_option("--masking", a->masking, "the masking-shadowing form: height-correlated (default, pbrt-v4) or separable "
                                           "(G1(wi) G1(wo), Mitsuba 3)");
  sub->add_option("--sampling", a->sampling,
                  "the normals the BSDF's sample() draws, which its pdf() is the density of: vndf (default: the visible "
                  "normals, Heitz 2018) or ndf (D(m) cos, Walter et al. 2007: Mitsuba 3's sample_visible = false)");
  sub->add_option("--frame", a->frame, "the frame of the rows: z-up or y-up")->capture_default_str();
  sub->add_option("--arithmetic", a->arithmetic,
                  "the renderer's arithmetic, float32 or float64 (the tolerances follow it)")
      ->capture_default_str();
  add_number_option(sub, "--worst", a->worst, integer(0, 1000), "pairs listed, the worst first")->default_str("10");
  sub->add_option("--model", a->model,
                  "the reference: exact (the single-scattering BSDF, pointwise) or smith-walk (its multiple scattering, "
                  "by the walk's next-event estimate)")
      ->capture_default_str();
  add_number_option(sub, "--paths", a->paths, whole(16, 100'000'000), "smith-walk: walks per pair (fewer underestimate the walk's error where rare long paths dominate)")->default_str("32768");
  add_number_option(sub, "--seed", a->seed, whole(), "smith-walk: seed of the walks")->default_str("1");
  add_number_option(sub, "--level", a->level, level(), "smith-walk: significance level of the chi-square")->default_str("0.01");
  sub->add_option("--json", a->json, "write the report as JSON");
  on_selected(sub, [a] { return run_check_eval(*a); });
}};

}  // namespace
}  // namespace microsim::app
