// experiment: the validation kind (measurement.h): one chi-square validation at the planned sample count (the
// power rule needs no rounds, plan.h validation_samples). A zoo sampler's samples drawn against its claimed
// pdf (the ranks tally shards of the samples' blocks, merged in order: validate_sampler's report, bit for bit);
// a dump's samples against the density it claims (validate_sample_file, streamed, on the root); either against
// the visible normals traced on a tile (its rays split like a VNDF's, the samples compared on the root).
// Cancelled: nothing is kept (the validator has no partial result), it runs again on resumption.
#include "experiment/plan_kinds.h"
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "experiment/report_html.h"
#include "microfacet/samplers.h"
#include "experiment/measures.h"

#include "core/errors.h"
#include "core/wall_clock.h"
#include "validate/compare.h"
#include "validate/sample_io.h"
#include "validate/validation_part.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>

namespace microsim::experiment {
namespace {

// The validator's options of a validation quantity: `samples` drawn from `seed` (0, 0 for a dump, whose samples
// are given) at the quantity's rows and level, the same for the root and every rank of a split one.
ValidationOptions validation_request(const SpecQuantity& quantity, std::uint64_t samples, std::uint64_t seed,
                                     const RunControl& run) {
  ValidationOptions v;
  v.samples = samples;
  v.seed = seed;
  v.rows = quantity.rows;
  v.significance = quantity.significance;
  v.run = run;
  return v;
}

// Bad input in a validation's dump (a file that is not samples, too few of them), naming the spec key.
std::invalid_argument dump_error(const SpecQuantity& quantity, const std::exception& e) {
  return std::invalid_argument(fmt::format("{}.dump: {}", quantity.key, e.what()));
}

DirectionSampleReader open_dump(const SpecQuantity& quantity) {
  DirectionSampleReader reader{std::filesystem::path(quantity.dump), SampleColumns::parse(quantity.dump_columns)};
  reader.set_frame(quantity.dump_frame == "y-up" ? SampleFrame::y_up : SampleFrame::z_up);
  return reader;
}

DumpClaims dump_claims(const SpecQuantity& quantity, const SpecMaterial& material) {
  return {parse_file_pdf(quantity.dump_pdf), dump_has_bsdf(quantity) ? std::optional<Material>(material.facet) : std::nullopt,
          quantity.above_horizon, quantity.lost_as_zero_weight};
}

// The validator's binned counts as a histogram (counts, and the claimed pdf's bin probabilities): what the
// report draws and validation-K.exr keeps.
TracedHistogram validation_histogram(const ValidationReport& r, const Decision& d) {
  TracedHistogram h;
  for (const BinnedComparison& c : r.histograms) {
    h.binnings.push_back(c.binning);
    std::vector<std::uint64_t> counts;
    std::vector<double> probability;
    for (std::size_t i = 0; i < c.observed.size(); ++i) {
      counts.push_back(std::uint64_t(std::llround(c.observed[i])));
      probability.push_back(r.samples > 0 ? c.expected[i] / double(r.samples) : 0.0);
    }
    h.counts.push_back(std::move(counts));
    h.probability.push_back(std::move(probability));
  }
  h.rays = h.hits = r.samples;
  h.attributes = {{"surface", "sampler " + r.sampler},
                  {"alpha", fmt::format("{},{}", d.alpha.first, d.alpha.second)},
                  {"theta", fmt::format("{}", d.view.theta_deg)},
                  {"phi", fmt::format("{}", d.view.phi_deg)},
                  {"seed", std::to_string(r.seed)}};
  return h;
}

// The TV deviation `samples` rows of a dump detect against its analytic reference (their count is the file's,
// not planned: plan.h detectable_tv).
double dump_detected_tv(const SpecQuantity& q, std::uint64_t samples) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  return detectable_tv(std::max<std::uint64_t>(samples, 1), tests.dof, tests.level, q.power);
}

class ValidationMeasurement : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the smallest TV deviation detected with power {} at level {} by the samples run", quantity_.power,
                       quantity_.significance);
  }
  bool shared() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return first_round_task(index, seed, first_units(decision_, 1), kSampleBlock);
  }
  void read_back(const std::filesystem::path& exr, MeasurementResult& m) const override {
    if (m.values.contains("validation")) m.histogram = read_histogram_exr(exr);  // the report's counts
  }

protected:
  Vec3<double> view() const { return direction_from_degrees(decision_.view.theta_deg, decision_.view.phi_deg); }
  GGX<double> ggx() const { return GGX<double>(decision_.alpha.first, decision_.alpha.second); }
  // The validation's result: the deviation its samples detect (N ~ 1 / tv^2, plan.h: the planned count detects
  // the target), the report and counts.
  void record(const ValidationReport& r, std::uint64_t planned, double seconds, MeasurementResult& m) const {
    m.achieved = detected(r.samples);
    m.units = m.rays = r.samples;
    m.rounds.push_back({r.samples, planned, 0, false, r.seed, 0, seconds, m.achieved});
    m.values = {{"validation", to_json(r)}};
    m.histogram = validation_histogram(r, decision_);
    m.met = m.achieved <= m.target * (1 + 1e-12);
  }
  virtual double detected(std::uint64_t samples) const {
    return quantity_.target * std::sqrt(double(decision_.units) / double(std::max<std::uint64_t>(samples, 1)));
  }
  [[noreturn]] void rethrow_dump_error(const std::exception& e) const { throw dump_error(quantity_, e); }
};

// A zoo sampler's samples drawn against its claimed pdf, split over the ranks.
class DrawnValidation final : public ValidationMeasurement {
public:
  using ValidationMeasurement::ValidationMeasurement;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run, SurfaceCache&) const override {
    const SamplerInfo* sampler = find_sampler(quantity_.sampler);
    if (sampler == nullptr) throw InternalError(fmt::format("a split validation of an unknown sampler '{}'", quantity_.sampler));
    const ValidationOptions options = validation_request(quantity_, task.units, task.seed, run);
    const ValidationRun drawn = drawn_validation_run(validation(*sampler, task.seed), options);
    return validation_round_part(task, mine, own_validation_part(drawn, mine));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const SamplerInfo* sampler = find_sampler(quantity_.sampler);
    if (sampler == nullptr)
      throw std::invalid_argument(fmt::format("{}.sampler: unknown sampler '{}'", quantity_.key, quantity_.sampler));
    const ValidationOptions v =
        validation_request(quantity_, first_units(decision_, c.options.cost_factor), c.round_seed(0), c.options.run);
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      const ValidationReport r = split_validation(c.split(), c.index, validation(*sampler, v.seed), v);
      record(r, r.samples, seconds_since(clock), m);
    });
  }

private:
  // The sampler's validation at this decision's roughness and view, from `seed`.
  ValidationCase validation(const SamplerInfo& sampler, std::uint64_t seed) const {
    return {&sampler, decision_.alpha.first, decision_.alpha.second, decision_.view.theta_deg, decision_.view.phi_deg, seed};
  }
};

// A dump: every sample of the file against the density it claims, its weights against its material's BSDF in
// its convention (validate_dump_as_given, streamed; light from inside a dielectric mirrored). A file that
// cannot be read, or holds too few samples, is bad input (std::invalid_argument naming the spec key). Not
// shared: the root reads the file.
class DumpValidation final : public ValidationMeasurement {
public:
  using ValidationMeasurement::ValidationMeasurement;
  std::string error_measure() const override {
    return fmt::format("the smallest TV deviation detected with power {} at level {} by the dump's rows{}",
                       quantity_.power, quantity_.significance,
                       quantity_.target > 0 ? "" : " (no detect_tv asked: the target is what they detect)");
  }
  // A dump without detect_tv: what the plan's count of its rows detects.
  double target() const override {
    return quantity_.target > 0 ? quantity_.target : dump_detected_tv(quantity_, decision_.units);
  }
  bool shared() const override { return false; }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const SpecQuantity& q = quantity_;
    ValidationOptions v = validation_request(q, 0, 0, c.options.run);
    const DumpClaims claims = dump_claims(q, material());
    if (SampleColumns::parse(q.dump_columns).channels() > 0) v.bsdf = claims.bsdf;  // the weight test
    v.convention = q.convention;
    if (q.dump_dropped > 0) v.dropped_below_horizon = q.dump_dropped;
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      try {
        DirectionSampleReader reader = open_dump(q);
        ValidationReport r = validate_dump_as_given(reader, claims, ggx(), view(), v, q.dump_frame == "z-up");
        r.sampler = q.dump;
        record(r, decision_.units, seconds_since(clock), m);
      } catch (const SampleFileError& e) {
        rethrow_dump_error(e);
      } catch (const InsufficientData& e) {
        rethrow_dump_error(e);
      }
    });
  }

private:
  double detected(std::uint64_t samples) const override { return dump_detected_tv(quantity_, samples); }
};

// Against the tile's traced visible normals (plan_heightfield_validation below): the planned rays traced in
// one round of round seed 1 (split like a VNDF's), then the sampler's samples (drawn as validate_sampler draws
// them, from round seed 0) or the dump's against them on the root (validate/compare.h).
class TileValidation final : public ValidationMeasurement {
public:
  using ValidationMeasurement::ValidationMeasurement;
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return first_round_task(index, seed, first_units(decision_, 1), kRaysPerBlock, 1);
  }
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    return tile_vndf_part(spec_, decision_, task, mine, run, surfaces);
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const microgeom::Heightfield* field = decision_surface_or_null(decision_, c.surfaces, c.options.run);
    m.partial = field == nullptr;  // its build cancelled
    if (field == nullptr) return;
    const SceneOf scene = [&c, field]() -> const HeightfieldScene& { return c.surfaces.scene_for(*field); };
    compare(c, scene, *field, m);
  }

private:
  void compare(const RoundContext& c, const SceneOf& scene, const microgeom::Heightfield& field, MeasurementResult& m) const {
    const SpecQuantity& q = quantity_;
    const std::uint64_t n = first_units(decision_, c.options.cost_factor);
    m.rounds.clear();
    const auto clock = std::chrono::steady_clock::now();
    const HeightfieldVndf traced = split_heightfield_vndf_round(
        c.split(), c.index, scene, field, surface_label(decision_.surface),
        vndf_request(spec_, decision_, n, c.round_seed(1), c.options.run));
    const ValidationOptions v = validation_request(q, n, c.round_seed(0), c.options.run);
    try {
      if (traced.trace.partial) throw Cancelled("the validation's rays");
      ValidationReport r;
      if (q.dump.empty()) {
        r = compare_sampler_to_trace(*find_sampler(q.sampler), ggx(), view(), v, traced.histogram);
      } else {
        DirectionSampleReader reader = open_dump(q);
        r = compare_sample_file_to_trace(reader, q.dump, ggx(), view(), v, traced.histogram);
      }
      record(r, n, seconds_since(clock), m);
      m.values["validation"]["reference"] =
          fmt::format("{} rays traced on {}", traced.histogram.hits, surface_label(decision_.surface));
    } catch (const Cancelled&) {
      m.partial = true;
    } catch (const BiasedReference& e) {
      record_no_verdict(e, n, fmt::format("{} rays traced on {}", traced.histogram.hits, surface_label(decision_.surface)), m);
    } catch (const SampleFileError& e) {
      rethrow_dump_error(e);
    } catch (const InsufficientData& e) {
      if (q.dump.empty()) throw;
      rethrow_dump_error(e);
    }
  }
  // The tile's trace is not D_v at this sample count (compare.h reference_bias): no verdict, target not met.
  void record_no_verdict(const BiasedReference& e, std::uint64_t samples, const std::string& reference,
                         MeasurementResult& m) const {
    const SpecQuantity& q = quantity_;
    m.values = {{"validation", {{"verdict", "none"}, {"sampler", q.dump.empty() ? q.sampler : q.dump},
                                {"samples", samples}, {"no_verdict", e.what()}, {"reference", reference}}}};
    m.met = false;
  }
};


// ---- its plan ----------------------------------------------------------------------------------------------

// A dump's rows, read from the file (every row checked: a file that cannot be read as samples is bad input
// naming the spec's key, before anything runs). A second pass over the file, the run's being the first to test.
std::uint64_t dump_rows(const SpecQuantity& q, const RunControl& run) {
  try {
    DirectionSampleReader reader = open_dump(q);
    return count_dump_rows(reader, run);
  } catch (const SampleFileError& e) {
    throw dump_error(q, e);
  }
}

// The time of a drawn validation: its reference's cubature (paid once), then the samples at the rate of a
// pilot of kChunkBlocks blocks of them (as many as the validator runs at once: every thread busy).
void time_validation(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const SamplerInfo& sampler = *find_sampler(q.sampler);  // the spec names a zoo sampler (spec.cpp)
  const auto start = std::chrono::steady_clock::now();
  const auto reference = claimed_reference(sampler, GGX<double>(d.alpha.first, d.alpha.second),
                                           direction_from_degrees(d.view.theta_deg, d.view.phi_deg), q.rows);
  const auto drawn = std::chrono::steady_clock::now();
  const std::uint64_t pilot = std::min<std::uint64_t>(d.units, kChunkBlocks * kSampleBlock);
  tally_drawn_samples(sampler, *reference,
                      validation_request(q, pilot, derived_seed(plan_seed(spec, o), kValidationPilot, d.quantity), o.run));
  const double reference_seconds = std::chrono::duration<double>(drawn - start).count();
  const double tally_seconds = seconds_since(drawn);
  d.pilot_units = pilot;
  d.pilot_seconds = reference_seconds + tally_seconds;
  d.predicted_seconds = reference_seconds + predicted_seconds(d.units, pilot, tally_seconds);
}

// validation_samples for the quantity's detect_tv; a count no validation can draw is a SpecError naming the key.
std::uint64_t planned_samples(const ExperimentSpec& spec, const SpecQuantity& q, const ValidationTests& tests) {
  try {
    return validation_samples(q.target, tests.dof, tests.level, q.power);
  } catch (const std::invalid_argument& e) {
    throw SpecError(spec.source, q.line, q.key + ".detect_tv", e.what());
  }
}

// A dump against its analytic reference: every row is tested, so the count is the file's rows and the TV they
// detect follows from it; detect_tv, when the spec gives one, is a target those rows meet or not.
void plan_dump_validation(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = dump_rows(q, o.run);
  d.unit = "samples";
  const double detected = detectable_tv(d.units, tests.dof, tests.level, q.power);
  d.count_reason = fmt::format("the dump's {} rows (read from {}), all tested: they detect any deviation of TV {:.3g} "
                               "with power {} at level {:.3g} per binning (Sidak of {}), df {} (noncentrality >= 4 N "
                               "TV^2)", d.units, std::filesystem::path(q.dump).filename().string(), detected, q.power,
                               tests.level, q.significance, tests.dof);
  if (q.target > 0) {
    const std::uint64_t needed = planned_samples(spec, q, tests);
    d.count_reason += fmt::format("; detect_tv {} needs {} rows: {}", q.target, needed,
                                  d.units >= needed ? "the dump has them" : "the dump has fewer (target not met)");
  } else {
    d.count_reason += "; no detect_tv asked: the rows fix the TV detected";
  }
  d.runnable = true;
}

void plan_validation_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  if (!q.dump.empty()) return plan_dump_validation(spec, q, o, d);
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = planned_samples(spec, q, tests);
  d.unit = "samples";
  d.count_reason = fmt::format("chi-square power: df {}, level {:.3g} per binning (Sidak of {}), power {} against any "
                               "deviation of TV {} (noncentrality >= 4 N TV^2), at least 5 samples per cell",
                               tests.dof, tests.level, q.significance, q.power, q.target);
  time_validation(spec, q, o, d);
  d.runnable = true;
}

// Why a validation cannot be made against a tile's traced visible normals ("" when it can): the reference is
// D_v of the tile, so the samples must claim D_v (a zoo sampler of visible normals; a dump with pdf vndf).
std::string surface_validation_refusal(const SpecQuantity& q) {
  if (!q.dump.empty() && q.dump_pdf != "vndf")
    return fmt::format("a dump of pdf {} against a surface: the traced reference is the tile's visible normals (pdf "
                       "vndf only)", q.dump_pdf);
  if (!q.dump.empty())
    return SampleColumns::parse(q.dump_columns).channels() == 0 ? "" : "a dump with weights against a surface: the "
                                                                       "traced reference is the tile's visible normals "
                                                                       "(their weights are tested analytically)";
  const SamplerInfo& sampler = *find_sampler(q.sampler);  // the spec names a zoo sampler (spec.cpp)
  if (sampler.domain == SampleDomain::microfacet_normal && sampler.claims == ClaimedPdf::visible_normals) return "";
  return fmt::format("sampler {} does not claim the visible normals: the traced reference is the tile's visible "
                     "normals", sampler.name);
}

// A validation against the tile's traced visible normals (validate/compare.h: the two-sample chi-square in
// each binning of the traced histogram, Sidak-combined). A two-sample test of n samples against n rays has the
// noncentrality of a one-sample test of n / 2: twice the analytic validator's samples, and as many rays (at
// least twice the two-sample minimum of a pilot's proportions). The tile's bias is at most kBiasShare of the
// deviation to detect (its size rule), so a correct sampler is rejected little more often than the level says.
void plan_heightfield_validation(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o,
                                 const microgeom::Heightfield& field, SurfaceCache& cache, Decision& d) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  const auto start = std::chrono::steady_clock::now();
  const HeightfieldVndf pilot = trace_heightfield_vndf(
      cache.scene_for(field), field, surface_label(d.surface),
      vndf_request(spec, d, o.pilot_rays, derived_seed(plan_seed(spec, o), kVndfPilot, d.quantity), o.run));
  if (pilot.trace.partial) throw Cancelled("plan: validation pilot on the tile");
  const std::uint64_t minimum = 2 * trace_minimum_samples(pilot.histogram);
  d.units = std::max(2 * planned_samples(spec, q, tests), minimum);
  d.unit = "samples";
  d.count_reason = fmt::format("two-sample chi-square against as many rays traced on the tile: power {} at level {:.3g} "
                               "per binning (Sidak of {}), df {}, against any deviation of TV {}: twice the one-sample "
                               "count (noncentrality >= 4 (n/2) TV^2), at least twice the two-sample minimum of the "
                               "pilot's proportions ({})",
                               q.power, tests.level, q.significance, tests.dof, q.target, minimum);
  if (!q.dump.empty())
    d.count_reason += fmt::format("; the dump's {} rows (read from {}) are all tested, against the planned rays",
                                  dump_rows(q, o.run), std::filesystem::path(q.dump).filename().string());
  d.pilot_units = o.pilot_rays;
  d.pilot_seconds = seconds_since(start);
  d.pilot_error = 0;
  // The tracing scales with the rays (the samples' draws are cheaper and not timed).
  d.predicted_seconds = predicted_seconds(d.units, d.pilot_units, pilot.trace.seconds);
}

}  // namespace

static void plan_validation_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                                     std::vector<Decision>& out) {
  plan_views(spec, index, o, cache, {plan_validation_view, plan_heightfield_validation, surface_validation_refusal, false}, out);
}

static std::unique_ptr<Measurement> make_validation_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::heightfield) return std::make_unique<TileValidation>(spec, decision);
  if (!spec.quantities.at(decision.quantity).dump.empty()) return std::make_unique<DumpValidation>(spec, decision);
  return std::make_unique<DrawnValidation>(spec, decision);
}

// ---- its model --------------------------------------------------------------------------------------------------

namespace {
// A validation against its analytic reference: a zoo sampler's samples are drawn, a renderer's dump is read.
ModelChoice validation_choice(const SpecQuantity& q) {
  if (q.dump.empty())
    return {Model::analytic_validator, "a zoo sampler against the pdf it claims: the analytic reference by "
                                       "cubature (no tracing needed to know D_v)"};
  return {Model::analytic_validator,
          fmt::format("a renderer's dump ({}) against the density it claims (pdf {}{}{}): its rows are read, not drawn; "
                      "the analytic reference by cubature (no tracing needed)",
                      std::filesystem::path(q.dump).filename().string(), q.dump_pdf,
                      q.above_horizon        ? ", only the reflections above the horizon"
                      : q.lost_as_zero_weight ? ", the lost samples as rows of weight 0"
                                              : "",
                      q.dump_columns == "x,y,z" ? "" : fmt::format(", columns {}", q.dump_columns))};
}

}  // namespace

static ModelChoice validation_model(const SpecQuantity& q, const SpecMaterial&) {
  return q.surface.kind != SurfaceChoice::Kind::automatic ? explicit_surface_choice(q) : validation_choice(q);
}

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {

void read_zoo_sampler(const SpecTable& t, SpecQuantity& q) {
  for (const char* key : {"pdf", "above_horizon", "lost_as_zero_weight", "columns", "frame", "dropped", "transport", "masking",
                          "sampling"})
    if (t.has(key)) t.fail(key, fmt::format("{} applies to a dump (a zoo sampler's density is its own)", key));
  q.sampler = t.string("sampler");
  if (find_sampler(q.sampler) == nullptr)
    t.fail("sampler", fmt::format("{} is not a sampler of the zoo ({})", quote_excerpt(q.sampler), fmt::join(sampler_names(), ", ")));
}

// What a dump holds besides its directions: columns, frame, and for a BSDF's samples its weights' convention.
void read_dump_layout(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m) {
  q.dump_columns = t.string("columns", "x,y,z");
  try {
    (void)SampleColumns::parse(q.dump_columns);
  } catch (const std::invalid_argument& e) {
    t.fail("columns", e.what());
  }
  q.dump_frame = t.string("frame", "z-up");
  if (q.dump_frame != "z-up" && q.dump_frame != "y-up")
    t.fail("frame", fmt::format("{} is not a frame (z-up, y-up)", quote_excerpt(q.dump_frame)));
  const bool bsdf = dump_has_bsdf(q);
  if (bsdf && m.facet.kind() == MaterialKind::lambertian)
    t.fail("material", fmt::format("material {}: a BSDF dump's material is a mirror, a conductor or a dielectric",
                                   quote_excerpt(m.name)));
  for (const char* key : {"transport", "masking"})
    if (t.has(key) && !bsdf) t.fail(key, fmt::format("{} is the convention of a BSDF's weights: give pdf = \"bsdf\" or "
                                                     "weight columns", key));
  if (t.has("sampling") && q.dump_pdf != "bsdf")
    t.fail("sampling", "sampling is how a BSDF's sample() draws its normals: it sets the BSDF's own density (pdf = "
                       "\"bsdf\")");
  // Each convention key parsed into its field; a bad name fails naming the key.
  const auto read = [&t](const char* key, auto parse, auto& field) {
    if (!t.has(key)) return;
    try {
      field = parse(key, t.string(key));
    } catch (const std::invalid_argument& e) {
      t.fail(key, e.what());
    }
  };
  read("transport", parse_transport_mode, q.convention.transport);
  read("masking", parse_masking_form, q.convention.masking);
  read("sampling", parse_sampled_normals, q.convention.normals);
  if (SampleColumns::parse(q.dump_columns).channels() > 0)
    if (const std::string why = untested_weights_reason(m.facet, q.convention); !why.empty()) t.fail("sampling", why);
}

// A dump was sampled at one alpha and one view; its density is one the validator knows, or its material's BSDF.
void read_dump(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  const std::string name = t.string("dump");
  const std::filesystem::path path = spec_file_path(name, spec_dir);
  if (!std::filesystem::is_regular_file(path)) t.fail("dump", fmt::format("no sample file {}", quote_excerpt(path.string())));
  if (m.alphas.size() != 1 || q.directions.size() != 1)
    t.fail("dump", fmt::format("a dump is sampled at one alpha and one view (material {} has {} alpha(s), the quantity {} "
                               "view(s))", quote_excerpt(m.name), m.alphas.size(), q.directions.size()));
  q.dump = path.string();
  q.dump_pdf = t.string("pdf", "vndf");
  FilePdf pdf = FilePdf::vndf;
  try {
    pdf = parse_file_pdf(q.dump_pdf);
  } catch (const std::invalid_argument& e) {
    t.fail("pdf", e.what());
  }
  read_dump_layout(t, q, m);
  if (q.directions.front().theta_deg > 90 && !(dump_has_bsdf(q) && m.facet.transmits()))
    t.fail("theta", "a view below the surface is light from inside a dielectric: its dump needs pdf = \"bsdf\" (or "
                    "weight columns) and a dielectric material");
  q.above_horizon = t.boolean("above_horizon", false);
  if (q.above_horizon && !claims_reflected_directions(pdf))
    t.fail("above_horizon", fmt::format("pdf {} is a density of normals (none is below the horizon)", q.dump_pdf));
  if (t.has("dropped") && !q.above_horizon) t.fail("dropped", "dropped applies with above_horizon = true only");
  q.dump_dropped = std::uint64_t(t.integer("dropped", 0, 0, std::int64_t(1) << 53));
  q.lost_as_zero_weight = t.boolean("lost_as_zero_weight", false);
  if (q.lost_as_zero_weight && q.above_horizon)
    t.fail("lost_as_zero_weight", "the lost samples are dropped (above_horizon) or kept as rows of weight 0, not both");
  if (q.lost_as_zero_weight && SampleColumns::parse(q.dump_columns).channels() == 0)
    t.fail("lost_as_zero_weight", "the rows of weight 0 need weight columns (columns = \"x,y,z,pdf,weight\")");
}

// A dump validated against its analytic reference needs no detect_tv: its rows are given, and they fix the TV
// detected (the plan states it). Against a surface it does: the tile is sized from it.
void read_validation_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m,
                          const std::filesystem::path& spec_dir) {
  const bool rows_fix_it = t.has("dump") && !t.has("detect_tv") && q.surface.kind == SurfaceChoice::Kind::automatic;
  q.target = rows_fix_it ? 0.0 : read_target(t, "detect_tv", 1, "a TV distance is below 1");
  q.directions = read_directions(t, t.has("dump") && m.facet.transmits());
  read_validator_rows(t, q, m);
  if (t.has("sampler") == t.has("dump"))
    t.fail("sampler", "give exactly one of sampler (a zoo sampler, drawn) and dump (a file of samples)");
  if (t.has("dump")) read_dump(t, q, m, spec_dir);
  else read_zoo_sampler(t, q);
  q.power = t.number("power", 0.9);
  q.significance = t.number("significance", 0.01);
  if (!(q.power > 0 && q.power < 1)) t.fail("power", fmt::format("{} must be in (0, 1)", q.power));
  if (!(q.significance > 0 && q.significance < 0.5)) t.fail("significance", fmt::format("{} must be in (0, 0.5)", q.significance));
}

}  // namespace

namespace {
// A dump's keys (the path names the dump: a file replaced under the same path is not detected); those beyond
// the first three only when not their defaults (the digests of earlier specs hold).
nlohmann::json validation_canonical(const SpecQuantity& q) {
  if (q.dump.empty()) return nlohmann::json::object();
  nlohmann::json j{{"dump", q.dump}, {"pdf", q.dump_pdf}, {"above_horizon", q.above_horizon}};
  if (q.dump_columns != "x,y,z") j["columns"] = q.dump_columns;
  if (q.dump_frame != "z-up") j["frame"] = q.dump_frame;
  if (q.dump_dropped != 0) j["dropped"] = q.dump_dropped;
  if (q.lost_as_zero_weight) j["lost_as_zero_weight"] = true;
  if (q.convention != BsdfConvention{}) j["convention"] = describe(q.convention);
  return j;
}
}  // namespace

const KindSpec validation_spec{"sampler dump pdf above_horizon lost_as_zero_weight detect_tv power significance theta "
                               "theta_range phi rows columns frame dropped transport masking sampling", read_validation_spec, validation_canonical};

// ---- its report section (report_html.h) -----------------------------------------------------------------------

namespace html {
namespace {

std::string validation_tests_table(const json& v) {
  std::string body;
  for (const auto& [name, t] : member(v, "tests").items()) {
    std::vector<std::string> cells{esc(name)};
    for (const char* key : {"statistic", "dof", "p_value"}) cells.push_back(t.contains(key) ? report_number(t[key]) : "-");
    if (t.contains("rejected")) cells.push_back(text_of(t["rejected"]));
    else cells.push_back(t.contains("passed") ? (t["passed"].get<bool>() ? "no" : "yes") : "-");
    body += row(cells);
  }
  return table({"test", "statistic", "dof", "p", "rejected"}, body);
}

std::string validation_values(const json& values, const ReportHistograms& histograms, std::size_t index,
                              const std::string& label) {
  const json& v = member(values, "validation");
  if (v.contains("no_verdict"))
    return fmt::format("<p class=\"notmet\">No verdict ({} against {}): {}.</p>\n", esc(text_of(member(v, "sampler"))),
                       esc(text_of(member(v, "reference"))), esc(text_of(member(v, "no_verdict"))));
  std::string out = fmt::format("<p>Sampler <b>{}</b>, {} samples: verdict <b>{}</b> (p {}, level {}).</p>\n",
                                esc(text_of(member(v, "sampler"))), text_of(member(v, "samples")),
                                esc(text_of(member(v, "verdict"))), report_number(member(v, "p_value")),
                                report_number(member(v, "significance")));
  for (const json& f : member(v, "failures")) out += "<p class=\"notmet\">" + esc(text_of(f)) + "</p>\n";
  out += validation_tests_table(v);
  const auto h = histograms.find(index);
  if (h != histograms.end()) out += histogram_figure(h->second, label, "claimed pdf");
  return out + fmt::format("<p>Counts: <a href=\"validation-{0}.exr\">validation-{0}.exr</a>.</p>\n", index);
}

}  // namespace
}  // namespace html

static std::string validation_report(const nlohmann::json& values, std::size_t index, const ReportHistograms& histograms,
                                     const ReportScatters&, const std::string& label) {
  return values.contains("validation") ? html::validation_values(values, histograms, index, label) : "";
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind validation_kind{"validation", &validation_spec, true, validation_model,
                                             plan_validation_quantity, make_validation_measurement, validation_report,
                                             nullptr, "validation"};

}  // namespace microsim::experiment
