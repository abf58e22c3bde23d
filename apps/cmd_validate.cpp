// microsim validate: statistical validation of a sampler of the zoo, of samples from a file, or of the
// whole zoo over a grid (--all). Tables on stdout, progress on stderr, --json for machines; the report is
// rendered by validate_report.h (shared with `microsim merge`). With --shard K/N only block range K of N of
// every validation's samples is drawn and --json holds the partial result (measure/validation.h).
// Exit codes: 0 pass (a shard: written), 1 rejected, 2 bad usage or bad input, 130 interrupted.
// See docs/reference/validator.md.
#include "command.h"
#include "validate_walk.h"
#include "number_options.h"
#include "microfacet/roughness.h"

#include "core/atomic_file.h"
#include "core/parse.h"
#include "measure/validation.h"
#include "progress_bar.h"
#include "validate/bsdf_validation.h"
#include "validate/compare.h"
#include "validate/dump_validation.h"
#include "validate/sample_io.h"
#include "validate/validate.h"
#include "validate_report.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace {

using microsim::app::UsageError;
namespace fs = std::filesystem;

struct Args {
  std::string sampler;
  std::string from;
  bool reflected = false;
  std::string pdf;                          // with --from: the density it claims (FilePdf), "" = by --reflected
  std::string frame;                        // with --from: "z-up" (default) or "y-up"
  std::string columns;                      // with --from: what the columns hold (SampleColumns::parse)
  std::string bsdf;                         // with --from and weight columns: mirror, conductor or a material spec
  std::string eta, k;                       // with --bsdf conductor: per channel
  std::string transport;                    // with --bsdf: radiance (default) or importance
  std::string masking;                      // with --bsdf: height-correlated (default) or separable
  std::string sampling;                     // with --bsdf: the normals sample() draws, vndf (default) or ndf
  bool above_horizon = false;               // with --reflected: the dump holds the reflections above it only
  bool lost_as_zero_weight = false;         // the dump keeps its sampler's lost samples as rows of weight 0
  std::optional<long long> dropped;         // with --above-horizon: how many the renderer dropped below it
  bool all = false;
  std::string alpha;
  std::optional<double> theta;
  double phi = 0;
  std::optional<long long> samples;
  unsigned long long seed = 1;
  bool use_float = false;
  std::optional<int> rows;  // default kDefaultRows; a traced histogram (--against HIST.exr) has its own
  double significance = 0.01;
  std::string json;
  std::string against;             // "ellipsoid" or a traced histogram HIST.exr (compare.h)
  std::optional<long long> rays;   // with --against ellipsoid
  std::string plot;                // a figure of the binned counts (SVG), single validations only
  std::string shard;               // "K/N": draw only block range K of N of the samples (a partial result)
  std::string model;               // "smith-walk": --from against the Smith random walk (validate_walk.h)
  std::string material;            // with --model smith-walk
  std::optional<long long> paths;  // with --model smith-walk: the walk's paths
};

constexpr long long kAllDefaultSamples = 200'000;
constexpr int kDefaultRows = 31;

std::string names_list() {
  std::string s;
  for (const auto& n : microsim::sampler_names()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

std::optional<microsim::Material> bsdf_of(const Args& a);
microsim::SampleColumns sample_columns(const Args& a);

// --bsdf dielectric --eta ETA: one real index (no --k: a dielectric does not absorb).
microsim::Material dielectric_of(const Args& a) {
  if (!a.k.empty()) throw UsageError("--k applies to --bsdf conductor; a dielectric takes --eta only");
  if (a.eta.empty()) throw UsageError("--bsdf dielectric needs --eta (the index inside over outside, e.g. 1.5)");
  const auto eta = microsim::parse_double_list("--eta", a.eta, {0.0, INFINITY, true, false}, 1);
  return microsim::Material::dielectric(eta.front());
}

// The convention of the --bsdf's weights: --transport (radiance unless said) and --masking (height-correlated).
microsim::BsdfConvention bsdf_convention(const Args& a) {
  microsim::BsdfConvention c;
  try {
    if (!a.transport.empty()) c.transport = microsim::parse_transport_mode("--transport", a.transport);
    if (!a.masking.empty()) c.masking = microsim::parse_masking_form("--masking", a.masking);
    if (!a.sampling.empty()) c.normals = microsim::parse_sampled_normals("--sampling", a.sampling);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return c;
}

microsim::ValidationOptions base_options(const Args& a) {
  microsim::ValidationOptions o;
  o.seed = a.seed;
  o.rows = a.rows.value_or(kDefaultRows);
  o.significance = a.significance;
  o.precision = a.use_float ? microsim::Precision::float32 : microsim::Precision::float64;
  if (a.dropped) o.dropped_below_horizon = std::uint64_t(*a.dropped);
  if (sample_columns(a).channels() > 0) o.bsdf = bsdf_of(a);  // the weight test (--pdf bsdf may come without it)
  o.convention = bsdf_convention(a);
  return o;
}

// Runs a validation; a malformed --from file (the reader's message names the line or index) and too few
// samples for the tests (the message says how many are needed) are bad input: exit 2.
template <class F> auto usage_errors_of(F&& validation, const std::string& file = "") {
  const std::string where = file.empty() ? "" : fmt::format("--from '{}': ", file);
  try {
    return validation();
  } catch (const microsim::SampleFileError& e) {
    throw UsageError(e.what());
  } catch (const microsim::InsufficientData& e) {
    throw UsageError(where + e.what());
  }
}

// The density a --from file claims: --pdf NAME, or --reflected for the reflection pdf, or with --bsdf the
// BSDF's own outgoing density (its samples are its outgoing directions), else the VNDF.
microsim::FilePdf file_pdf(const Args& a) {
  if (a.pdf.empty()) {
    if (a.reflected) return microsim::FilePdf::reflection;
    return a.bsdf.empty() || !a.against.empty() ? microsim::FilePdf::vndf : microsim::FilePdf::bsdf;
  }
  try {
    return microsim::parse_file_pdf(a.pdf);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--pdf: {}", e.what()));
  }
}

// The frame of a --from file's rows: --frame z-up (default) or y-up.
microsim::SampleFrame sample_frame(const Args& a) {
  if (a.frame.empty() || a.frame == "z-up") return microsim::SampleFrame::z_up;
  if (a.frame == "y-up") return microsim::SampleFrame::y_up;
  throw UsageError(fmt::format("--frame: unknown frame '{}' (valid: z-up, y-up)", a.frame));
}

// A --from file, opened for streaming (bounded memory whatever its size), its rows in the frame of --frame.
microsim::SampleColumns sample_columns(const Args& a) {
  if (a.columns.empty()) return {};
  try {
    return microsim::SampleColumns::parse(a.columns);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--columns {}", e.what()));
  }
}

// The BSDF of --bsdf: "mirror", "conductor" with --eta and --k (one value per channel), "dielectric" with
// --eta (the inside's index over the outside's), or a material spec as `scatter --material` takes
// ("conductor:0.2,3.9;0.9,2.4", "dielectric:1.5").
std::optional<microsim::Material> bsdf_of(const Args& a) {
  using microsim::Material;
  if (a.bsdf.empty()) {
    if (!a.eta.empty() || !a.k.empty()) throw UsageError("--eta and --k apply with --bsdf conductor or dielectric only");
    return std::nullopt;
  }
  try {
    if (a.bsdf.find(':') != std::string::npos || a.bsdf == "mirror") {
      if (!a.eta.empty() || !a.k.empty()) throw UsageError(fmt::format("--eta and --k apply to --bsdf conductor or dielectric, not '{}'", a.bsdf));
      return microsim::parse_material("--bsdf", a.bsdf);
    }
    if (a.bsdf == "dielectric") return dielectric_of(a);
    if (a.bsdf != "conductor")
      throw UsageError(fmt::format("--bsdf: unknown BSDF '{}' (valid: mirror, conductor with --eta and --k, dielectric "
                                   "with --eta, or a spec like conductor:0.2,3.9)",
                                   a.bsdf));
    if (a.eta.empty() || a.k.empty()) throw UsageError("--bsdf conductor needs --eta and --k (one value per weight column)");
    const auto eta = microsim::parse_double_list("--eta", a.eta, {0.0, INFINITY, true, false}, Material::kMaxChannels);
    const auto k = microsim::parse_double_list("--k", a.k, {0.0, INFINITY, false, false}, Material::kMaxChannels);
    if (eta.size() != k.size())
      throw UsageError(fmt::format("--eta has {} value(s) and --k {}: one pair per channel", eta.size(), k.size()));
    std::vector<std::complex<double>> ior;
    for (std::size_t c = 0; c < eta.size(); ++c) ior.emplace_back(eta[c], k[c]);
    return Material::conductor(ior);
  } catch (const std::invalid_argument& e) {  // ParseError, a constructor's check
    throw UsageError(e.what());
  }
}

microsim::DirectionSampleReader open_samples_or_usage_error(const Args& a) {
  auto reader = usage_errors_of([&] { return microsim::DirectionSampleReader(a.from, sample_columns(a)); });
  reader.set_frame(sample_frame(a));
  return reader;
}

// --against ellipsoid | HIST.exr: two-sample chi-square against the traced oracle (compare.h); same report,
// verdict, exit codes and JSON keys (plus "against").
int run_against(const Args& a, const microsim::GGX<double>& ggx, const microsim::Vec3<double>& wi,
                microsim::ValidationOptions o) {
  using namespace microsim;
  // Too few samples for any test: refused before the oracle is traced.
  if (a.from.empty()) usage_errors_of([&] { require_samples_for_any_test(std::uint64_t(a.samples.value_or(1'000'000))); });
  const auto start = std::chrono::steady_clock::now();  // the reported time includes the oracle's tracing
  TracedHistogram traced;
  std::string oracle;
  if (a.against == "ellipsoid") {
    OracleTraceOptions t;
    t.rays = std::uint64_t(a.rays.value_or(4'000'000));
    t.seed = oracle_seed(a.seed);
    t.rows = a.rows.value_or(kDefaultRows);
    const auto progress = std::make_shared<CliProgress>(true);
    t.run = cli_run_control(0, progress);
    traced = trace_vndf_histogram(ggx, wi, t);
    progress->finish();
    if (traced.partial) return microsim::app::interrupted_nothing_written("validate", "while tracing the oracle", "no verdict");
    oracle = fmt::format("the traced ellipsoid ({} rays, {} hits, seed {})", traced.rays, traced.hits, t.seed);
  } else {
    traced = microsim::app::read_oracle_histogram("--against", a.against);
    oracle = microsim::app::histogram_oracle(a.against, traced);
  }
  ValidationReport report;
  std::string source;
  try {
    if (!a.from.empty()) {
      DirectionSampleReader samples = open_samples_or_usage_error(a);
      report = usage_errors_of([&] { return compare_sample_file_to_trace(samples, a.from, ggx, wi, o, traced); }, a.from);
      source = fmt::format("samples from '{}'", a.from);
    } else {
      const SamplerInfo* s = find_sampler(a.sampler);
      if (!s) throw UsageError(fmt::format("--sampler: unknown sampler '{}' (valid: {})", a.sampler, names_list()));
      o.samples = std::uint64_t(a.samples.value_or(1'000'000));
      report = usage_errors_of([&] { return compare_sampler_to_trace(*s, ggx, wi, o, traced); });
      source = microsim::app::sampler_source(*s);
    }
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--against: {}", e.what()));
  }
  if (interrupted()) return microsim::app::interrupted_nothing_written("validate", "while comparing with the oracle", "no verdict");
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return microsim::app::report_validation(report, microsim::app::oracle_source(source, oracle), {a.json, a.plot},
                                          {{"against", a.against}, {"oracle_rays", traced.rays}, {"oracle_hits", traced.hits}});
}

// ---- --shard K/N: a partial result -------------------------------------------------------------------------

// The run of `validate --sampler` (one case) or `--all` (the zoo), as a shard draws it.
microsim::ValidationRun validation_run(const Args& a, const microsim::SamplerInfo* sampler) {
  using namespace microsim;
  ValidationRun run;
  run.batch = a.all;
  run.seed = a.seed;
  run.family_significance = a.significance;
  run.options = base_options(a);
  run.options.samples = std::uint64_t(a.samples.value_or(a.all ? kAllDefaultSamples : 1'000'000));
  run.against = a.against;
  if (a.all) {
    run.cases = zoo_cases(a.seed);
    run.options.significance = sidak_significance(a.significance, int(run.cases.size()));
  } else {
    const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
    run.cases = {{sampler, ax, ay, *a.theta, a.phi, a.seed}};
  }
  return run;
}

// Draws block range K of N of every validation of the run and writes the partial result to --json.
int run_shard(const Args& a, const microsim::SamplerInfo* sampler) {
  using namespace microsim;
  const ValidationRun run = validation_run(a, sampler);
  usage_errors_of([&] { require_samples_for_any_test(run.options.samples); });
  const std::uint64_t blocks = validation_blocks(run);
  const ShardSpec shard = parse_shard("--shard", a.shard, blocks);  // ParseError: exit 2
  std::optional<TracedHistogram> traced;
  if (!a.against.empty()) traced = microsim::app::read_oracle_histogram("--against", a.against);
  install_interrupt_handler();
  const auto progress = std::make_shared<CliProgress>(true);
  ValidationRun drawn = run;
  drawn.options.run = cli_run_control(0, progress);
  ValidationPart part;
  try {
    part = usage_errors_of([&] {
      return sample_validation_part(drawn, shard_range(blocks, shard.index, shard.count), traced ? &*traced : nullptr);
    });
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--against: {}", e.what()));
  }
  progress->finish();
  write_file_atomically(a.json, validation_part_json(part).dump() + "\n");
  fmt::print(stderr, "validate: shard {}: blocks {} of {} of {} validation(s), written to '{}'; join the parts with "
             "`microsim merge PART.json... --json RESULT.json`\n",
             a.shard, part.provenance.blocks.to_string(), blocks, run.cases.size(), a.json);
  return microsim::app::kExitOk;
}

// What --shard K/N cannot split, and what it needs, checked before any work.
void check_shard(const Args& a) {
  if (a.shard.empty()) return;
  if (!a.from.empty())
    throw UsageError(fmt::format("--shard {} with --from: the samples of a file are given, not drawn (nothing to shard)",
                                 a.shard));
  if (a.against == "ellipsoid")
    throw UsageError(fmt::format("--shard {} with --against ellipsoid: every shard would trace the whole oracle; trace "
                                 "it once (`microsim trace vndf ... --out HIST.exr`, itself shardable) and compare "
                                 "with --against HIST.exr",
                                 a.shard));
  if (!a.plot.empty()) throw UsageError(fmt::format("--shard {} with --plot: a shard has no verdict to draw", a.shard));
  if (a.json.empty())
    throw UsageError(fmt::format("--shard {}: needs --json PART.json (the partial result for `microsim merge`)", a.shard));
}

// --from FILE against the density it claims (dump_validation.h), light from inside a dielectric as its mirror
// image; the report keeps the view as given.
microsim::ValidationReport validate_file(const Args& a, const microsim::GGX<double>& ggx, const microsim::Vec3<double>& view,
                                         const microsim::ValidationOptions& o) {
  using namespace microsim;
  DirectionSampleReader samples = open_samples_or_usage_error(a);
  const DumpClaims claims{file_pdf(a), bsdf_of(a), a.above_horizon, a.lost_as_zero_weight};
  try {
    (void)seen_from_outside(view, claims.bsdf);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--theta {:g}: {}", *a.theta, e.what()));
  }
  // A frame given explicitly is not second-guessed.
  ValidationReport report = usage_errors_of(
      [&] {
        try {
          return validate_dump_as_given(samples, claims, ggx, view, o, a.frame.empty());
        } catch (const InsufficientData&) {
          throw;
        } catch (const std::invalid_argument& e) {  // the claims' reference (dump_reference), named by the flag given
          throw UsageError(fmt::format("{}{}", a.lost_as_zero_weight ? "--lost-as-zero-weight: "
                                               : a.above_horizon    ? "--above-horizon: "
                                                                    : "",
                                       e.what()));
        }
      },
      a.from);
  report.sampler = a.from;
  return report;
}

int run_single(const Args& a) {
  using namespace microsim;
  if (a.alpha.empty()) throw UsageError("--alpha is required (e.g. --alpha 0.3 or --alpha 0.05,0.5)");
  if (!a.theta) throw UsageError("--theta is required (degrees in [0, 90); (90, 180] for light from inside a dielectric)");
  const auto [ax, ay] = microsim::parse_alpha("--alpha", a.alpha);
  const GGX<double> ggx(ax, ay);
  const Vec3<double> wi = direction_from_degrees(*a.theta, a.phi);
  const SamplerInfo* s = a.sampler.empty() ? nullptr : find_sampler(a.sampler);
  if (!a.sampler.empty() && !s)
    throw UsageError(fmt::format("--sampler: unknown sampler '{}' (valid: {})", a.sampler, names_list()));
  if (!a.shard.empty()) return run_shard(a, s);
  ValidationOptions o = base_options(a);
  const auto progress = std::make_shared<CliProgress>(true);
  o.run = cli_run_control(0, progress);
  install_interrupt_handler();
  if (!a.against.empty()) return run_against(a, ggx, wi, o);
  ValidationReport report;
  std::string source;
  if (!a.from.empty()) {
    report = validate_file(a, ggx, wi, o);
    source = fmt::format("samples from '{}'", a.from);
  } else {
    o.samples = std::uint64_t(a.samples.value_or(1'000'000));
    report = usage_errors_of([&] { return validate_sampler(*s, ggx, wi, o); });
    source = microsim::app::sampler_source(*s);
  }
  progress->finish();
  if (interrupted()) return microsim::app::interrupted_nothing_written("validate", "while validating", "no verdict");
  return microsim::app::report_validation(report, source, {a.json, a.plot});
}

int run_all(const Args& a) {
  using namespace microsim;
  if (!a.alpha.empty() || a.theta) throw UsageError("--all runs its own grid: drop --alpha/--theta/--phi");
  if (!a.shard.empty()) return run_shard(a, nullptr);
  install_interrupt_handler();
  ValidationRun run = validation_run(a, nullptr);
  // Too few samples for any test: refused before any work (each validation checks its own bound too).
  // Sidak over the batch: each validation (itself Sidak over its own tests) runs at the level that
  // keeps the family-wise level of the whole batch at --significance (validation_run).
  usage_errors_of([&] { require_samples_for_any_test(run.options.samples); });
  const microsim::app::ZooReport report(run);
  const auto progress = std::make_shared<CliProgress>(true);
  run.options.run = cli_run_control(0, progress);  // Ctrl-C stops the batch between validations
  const ZooResult result = usage_errors_of([&] { return validate_all(run, report.observer()); });
  progress->finish();
  return report.finish(result, a.json);
}

// The options that describe a --from file (what it claims, its columns, frame, BSDF): checked before any
// work, each refused where it does not apply.
void check_file_options(const Args& a) {
  if (!a.pdf.empty()) {
    if (a.from.empty()) throw UsageError("--pdf applies to --from FILE only (a sampler of the zoo claims its own pdf)");
    if (!a.against.empty()) throw UsageError("--pdf: --against compares with the traced VNDF oracle, not with a pdf");
    if (a.reflected && file_pdf(a) != microsim::FilePdf::reflection)
      throw UsageError(fmt::format("--reflected means --pdf reflection; it conflicts with --pdf {}", a.pdf));
    file_pdf(a);  // an unknown name is exit 2 here, before any work
  }
  if (a.above_horizon && (a.from.empty() || !microsim::claims_reflected_directions(file_pdf(a))))
    throw UsageError("--above-horizon applies to reflected directions: give --from FILE --reflected (or --pdf bounded)");
  if (a.above_horizon && !a.against.empty()) throw UsageError("--above-horizon tests against the analytic pdf, not --against");
  if (a.dropped && !a.above_horizon) throw UsageError("--dropped applies with --above-horizon only");
  if (a.lost_as_zero_weight && (a.from.empty() || !a.against.empty() || a.above_horizon || sample_columns(a).channels() == 0))
    throw UsageError("--lost-as-zero-weight applies to --from FILE with weight columns (--columns x,y,z,pdf,weight), "
                     "without --above-horizon (the lost samples are dropped or kept, not both) or --against");
  if (!a.frame.empty() && a.from.empty()) throw UsageError("--frame applies to --from FILE only");
  if (!a.columns.empty() && a.from.empty()) throw UsageError("--columns applies to --from FILE only");
  sample_columns(a);  // a bad spec is exit 2 here, before any work
  if (const auto bsdf = bsdf_of(a)) {
    if (a.from.empty() || !a.against.empty()) throw UsageError("--bsdf applies to --from FILE (its weight columns)");
    if (bsdf->transmits() && file_pdf(a) != microsim::FilePdf::bsdf)
      throw UsageError(fmt::format("--bsdf {}: a dielectric's dump holds reflections and refractions; test them against "
                                   "its sampling density (--pdf bsdf, implied by --bsdf), not --pdf {}",
                                   bsdf->describe(), a.reflected ? "reflection" : a.pdf));
    const bool directions_only = sample_columns(a).channels() == 0 && file_pdf(a) == microsim::FilePdf::bsdf;
    if (!directions_only && sample_columns(a).channels() != bsdf->channels())
      throw UsageError(fmt::format("--bsdf {} has {} channel(s): give as many weight columns (--columns x,y,z,weight...), "
                                   "got {}",
                                   bsdf->describe(), bsdf->channels(), sample_columns(a).channels()));
  }
  if ((!a.transport.empty() || !a.masking.empty()) && a.bsdf.empty())
    throw UsageError(fmt::format("{} is the convention of a BSDF's weights: give the BSDF with --bsdf",
                                 a.transport.empty() ? "--masking" : "--transport"));
  if (!a.sampling.empty() && (a.bsdf.empty() || file_pdf(a) != microsim::FilePdf::bsdf))
    throw UsageError("--sampling is how a BSDF's sample() draws its normals: it sets the BSDF's own density (--bsdf, "
                     "which implies --pdf bsdf), not that of --pdf or --reflected");
  if (const auto bsdf = bsdf_of(a); bsdf && sample_columns(a).channels() > 0)
    if (const std::string why = microsim::untested_weights_reason(*bsdf, bsdf_convention(a)); !why.empty())
      throw UsageError(fmt::format("--sampling {} with --columns {}: {}", a.sampling, a.columns, why));
  bsdf_convention(a);  // an unknown name is exit 2 here, before any work
  // Weights are f cos / pdf of a BSDF: without it they could not be tested, and a pass would look as if they were.
  if (const int weights = sample_columns(a).channels(); weights > 0 && a.bsdf.empty())
    throw UsageError(fmt::format("--columns {} names {} weight column(s): weights (f cos / pdf) are tested against the "
                                 "BSDF they come from: give it with --bsdf (mirror, conductor --eta --k, dielectric "
                                 "--eta), or mark the columns '-' to skip them",
                                 a.columns, weights));
  if (file_pdf(a) == microsim::FilePdf::bsdf && !bsdf_of(a))
    throw UsageError("--pdf bsdf is the sampling density of a BSDF: give it with --bsdf (e.g. --bsdf dielectric --eta 1.5)");
  sample_frame(a);  // an unknown frame is exit 2 here, before any work
}

// --from DUMP --model smith-walk: the options that apply, then the walk's validation.
int run_model(const Args& a) {
  if (a.model != "smith-walk") throw UsageError(fmt::format("--model {}: the model is smith-walk", a.model));
  if (a.from.empty()) throw UsageError("--model smith-walk validates a dump: give --from FILE");
  for (const auto& [given, name] : {std::pair{!a.sampler.empty() || a.all, "--sampler/--all"}, {!a.against.empty(), "--against"},
                                    {!a.bsdf.empty(), "--bsdf (give --material)"}, {!a.pdf.empty() || a.reflected, "--pdf/--reflected"},
                                    {a.above_horizon, "--above-horizon"}, {a.lost_as_zero_weight, "--lost-as-zero-weight"},
                                    {!a.plot.empty(), "--plot"}, {!a.shard.empty(), "--shard"},
                                    {!a.transport.empty() || !a.masking.empty() || !a.sampling.empty(),
                                     "--transport/--masking/--sampling"}})
    if (given) throw UsageError(fmt::format("{} does not apply to --model smith-walk", name));
  if (!a.theta) throw UsageError("--model smith-walk needs --theta");
  microsim::app::WalkValidationArgs w{a.from, a.columns, a.frame, a.material, a.alpha, a.json, *a.theta, a.phi,
                                      a.significance, a.paths, a.dropped, a.seed};
  return microsim::app::run_walk_validation(w);
}

int run(const Args& a) {
  if (!a.model.empty() || !a.material.empty() || a.paths) {
    if (a.model.empty()) throw UsageError("--material and --paths apply to --model smith-walk");
    return run_model(a);
  }
  microsim::app::check_distinct_outputs({{"--from", a.from}, {"--against", a.against == "ellipsoid" ? "" : a.against}},
                                        {{"--json", a.json}, {"--plot", a.plot}});
  const int modes = int(!a.sampler.empty()) + int(!a.from.empty()) + int(a.all);
  if (modes != 1) throw UsageError("give exactly one of --sampler NAME, --from FILE, --all");
  if (a.reflected && a.from.empty()) throw UsageError("--reflected applies to --from FILE only");
  check_file_options(a);
  if (a.use_float && !a.from.empty()) throw UsageError("--float applies to --sampler and --all, not to --from");
  if (a.samples && !a.from.empty()) throw UsageError("--samples does not apply to --from (the file gives the samples)");
  const bool inside = a.theta && *a.theta > 90 && *a.theta <= 180 && !a.from.empty() && a.against.empty();
  if (a.theta && !(*a.theta >= 0 && *a.theta < 90) && !inside)
    throw UsageError(fmt::format("--theta must be in [0, 90) degrees (or (90, 180] with --from and --bsdf dielectric: "
                                 "light from inside), got {}",
                                 *a.theta));
  if (!std::isfinite(a.phi)) throw UsageError(fmt::format("--phi must be finite, got {}", a.phi));
  if (!(a.significance > 0 && a.significance < 1))
    throw UsageError(fmt::format("--significance must be in (0, 1), got {}", a.significance));
  if (!a.against.empty()) {
    if (a.all) throw UsageError("--against applies to --sampler and --from, not to --all");
    if (a.reflected) throw UsageError("--against: the traced oracle measures microfacet normals, not reflected directions");
    if (a.against != "ellipsoid" && fs::path(a.against).extension() != ".exr")
      throw UsageError(fmt::format("--against '{}': use 'ellipsoid' or a histogram .exr from `microsim trace vndf`", a.against));
  }
  if (a.rays && a.against != "ellipsoid") throw UsageError("--rays applies to --against ellipsoid only");
  if (a.rows && !a.against.empty() && a.against != "ellipsoid")
    throw UsageError(fmt::format("--rows {}: a traced histogram ({}) is compared in its own binnings; leave --rows out",
                                 *a.rows, a.against));
  if (!a.plot.empty()) {
    if (a.all) throw UsageError("--plot draws one validation; it does not apply to --all");
    if (fs::path(a.plot).extension() != ".svg")
      throw UsageError(fmt::format("--plot: '{}' must end in .svg (the figure is SVG)", a.plot));
  }
  check_shard(a);
  microsim::app::check_output("--json", a.json);
  microsim::app::check_output("--plot", a.plot);
  return a.all ? run_all(a) : run_single(a);
}

// The options that say what a --from file holds: its columns, the BSDF and its conventions, its frame, and how
// it holds the samples its sampler lost.
void add_dump_options(CLI::App* sub, Args& a) {
  using microsim::app::add_number_option;
  sub->add_option("--columns", a.columns,
                  "with --from: what the columns of a row hold, e.g. x,y,z,pdf (the pdf the sampler returned: checked "
                  "against the claimed pdf at each sample) or x,y,z,pdf,weight (weights need --bsdf, the BSDF they are "
                  "tested against); '-' skips a column (default x,y,z)");
  sub->add_option("--bsdf", a.bsdf,
                  "with --from: the rows are this BSDF's samples, tested against its outgoing density (--pdf bsdf unless "
                  "--pdf or --reflected says otherwise) and, with weight columns, their weights (f cos / pdf) against "
                  "the BSDF: mirror, conductor (with --eta and --k), dielectric (with --eta) or a spec as scatter "
                  "--material takes (conductor:0.2,3.9;0.9,2.4, dielectric:1.5)");
  sub->add_option("--eta", a.eta,
                  "with --bsdf conductor: the real parts of the indices, one per weight column; with --bsdf dielectric: "
                  "the index inside over outside (a view from inside: mirror the rows and give 1 / eta)");
  sub->add_option("--k", a.k, "with --bsdf conductor: the imaginary parts, one per weight column");
  sub->add_option("--transport", a.transport,
                  "with --bsdf: the transport mode of the weights: radiance (default: camera paths; a refraction's weight "
                  "holds (n_given / n_sampled)^2, as pbrt-v4 and Mitsuba 3 in radiance mode) or importance (light "
                  "paths: no such factor)");
  sub->add_option("--masking", a.masking,
                  "with --bsdf: the masking-shadowing form of the BSDF: height-correlated (default, Smith's G2 = 1 / (1 "
                  "+ Lambda_i + Lambda_o), pbrt-v4) or separable (G1(wi) G1(wo), Mitsuba 3)");
  sub->add_option("--sampling", a.sampling,
                  "with --bsdf: the normals its sample() draws, which set the density of its directions: vndf (default: "
                  "the visible normals, Heitz 2018; pbrt-v4, Mitsuba 3) or ndf (D(m) cos, Walter et al. 2007: Mitsuba "
                  "3's sample_visible = false)");
  sub->add_option("--frame", a.frame,
                  "with --from: the frame of the rows: z-up (default, microsim's) or y-up (normal along +y, rotated to "
                  "z-up by (x, y, z) -> (x, -z, y); --theta/--phi stay z-up)");
  sub->add_flag("--above-horizon", a.above_horizon,
                "with --from --reflected: the file holds only the reflections above the horizon (as renderers emit "
                "them, dropping wo.z <= 0); test against the reflection pdf conditioned on wo.z > 0. With --pdf bsdf: "
                "the file holds the samples the sampler kept (a dielectric also loses its refractions above the "
                "horizon), tested against its density conditioned on them");
  sub->add_flag("--lost-as-zero-weight", a.lost_as_zero_weight,
                "with --from and weight columns: the file keeps the samples its sampler lost (a reflection below the "
                "horizon, a refraction on the wrong side) as rows of weight 0, as Mitsuba 3's sample() returns them; "
                "they count as the sampler's failures, tested against the mass the claimed pdf loses");
  add_number_option(sub, "--dropped", a.dropped, microsim::app::whole(0, microsim::kMaxSamples),
                    "with --above-horizon: how many samples the renderer dropped (reflections below the horizon, a "
                    "dielectric's refractions above it; tested against the fraction the pdf loses)");
}

microsim::app::CommandRegistration validate_registration{"validate", [](CLI::App& app) {
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "validate",
      "Statistical validation of a GGX sampler (chi-square in sphere and lobe bins, returned pdf, E[weight], pdf "
      "integral). Exit 0 pass (--shard: the part written), 1 rejected, 2 bad usage/input, 130 interrupted.");
  sub->add_option("--sampler", args->sampler, "sampler of the zoo to validate (" + names_list() + ")");
  sub->add_option("--from", args->from,
                  "validate samples from FILE instead: .npy (float32/float64, shape (N,3)) or text, one x y z per line");
  sub->add_flag("--reflected", args->reflected,
                "with --from: rows are reflected directions of VNDF sampling (= --pdf reflection; the bounded "
                "sampler's reflections: --pdf bounded alone), not normals");
  sub->add_option("--pdf", args->pdf,
                  "with --from: the density the samples claim: vndf (normals, default), ndf (normals, D(m) m.z), "
                  "bounded (reflections of the bounded VNDF, Eto & Tokuyoshi 2023), reflection (reflections of VNDF "
                  "sampling, = --reflected), bsdf (the outgoing directions of the --bsdf's VNDF sampling: a conductor's "
                  "reflections; a dielectric's reflections with probability F and refractions, over the whole sphere)");
  add_dump_options(sub, *args);
  sub->add_flag("--all", args->all, "validate the whole zoo over the standard grid (Sidak-corrected over the batch)");
  sub->add_option("--alpha", args->alpha,
                  "roughness AX or AX,AY, each in [1e-4, 10], anisotropy at most 1:1000 (docs/reference/conventions.md)");
  using microsim::app::add_number_option;
  add_number_option(sub, "--theta", args->theta, microsim::app::real(), "view zenith angle in degrees, [0, 90); with --from and --bsdf dielectric also (90, 180]: light from "
                    "inside the dielectric (the view below the surface)");
  add_number_option(sub, "--phi", args->phi, microsim::app::real(), "view azimuth in degrees (default 0)");
  add_number_option(sub, "--samples", args->samples, microsim::app::whole(1, microsim::kMaxSamples),
                    microsim::app::at_most("number of samples (default 1000000; 200000 per validation with --all)",
                                           microsim::kMaxSamples));
  add_number_option(sub, "--seed", args->seed, microsim::app::whole(), "random seed (default 1)");
  sub->add_flag("--float", args->use_float, "run the sampler's float version (default: double)");
  add_number_option(sub, "--rows", args->rows, microsim::app::binning_rows(3),
                    fmt::format("rows of the sphere and lobe binnings (odd, 3..{}; cols = 2 rows; default 31)",
                                microsim::kMaxBinningRows));
  add_number_option(sub, "--significance", args->significance, microsim::app::level(),
                    "family-wise significance level (default 0.01)");
  sub->add_option("--json", args->json, "write the results as JSON to PATH (atomically)");
  sub->add_option("--against", args->against,
                  "compare with the traced oracle instead of the analytic pdf (two-sample chi-square): 'ellipsoid' "
                  "(traced now) or a histogram HIST.exr from `microsim trace vndf`; refused (exit 2) when the histogram departs "
                  "from D_v (a tile's NDF tail and masking, a meshed ellipsoid) by more than the samples can afford: "
                  "an exact sampler would be rejected more than twice as often as the level (the largest count it "
                  "serves is named)");
  add_number_option(sub, "--rays", args->rays, microsim::app::whole(1, microsim::kMaxRays),
                    microsim::app::at_most("rays traced for --against ellipsoid (default 4000000)",
                                           microsim::kMaxRays));
  sub->add_option("--plot", args->plot,
                  "also draw FIG.svg: observed and expected counts and Pearson residuals in the sphere and lobe bins");
  sub->add_option("--shard", args->shard,
                  "--sampler (against its claimed pdf or --against HIST.exr) and --all: draw only shard K of N of "
                  "every validation's samples (K/N, 1-based: a contiguous range of its blocks of 65536 samples) and "
                  "write their exact counts to --json PART.json; `microsim merge` joins the N parts, computes the "
                  "expected counts (the cubature, which shards skip) and reports the single run, bit for bit. Not for "
                  "--from (given samples) or --against ellipsoid (shard its trace instead)");
  sub->add_option("--model", args->model,
                  "with --from: validate against a model's multiple scattering instead: smith-walk (the random walk of "
                  "Heitz et al. 2016; rows x,y,z,weight per channel, as --columns says): the lobe's shape and the "
                  "reflected and transmitted albedos against the walk's");
  sub->add_option("--material", args->material,
                  "with --model smith-walk: the facet material (mirror, conductor:ETA,K, dielectric:ETA)");
  add_number_option(sub, "--paths", args->paths, microsim::app::whole(1, microsim::kMaxSamples),
                    "with --model smith-walk: the walk's paths (default 2000000)");
  microsim::app::on_selected(sub, [args] { return run(*args); });
}};

}  // namespace
