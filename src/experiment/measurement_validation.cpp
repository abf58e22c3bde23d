// experiment: the validation kind (measurement.h): one chi-square validation at the planned sample count (the
// power rule needs no rounds, plan.h validation_samples). A zoo sampler's samples drawn against its claimed
// pdf (the ranks tally shards of the samples' blocks, merged in order: validate_sampler's report, bit for bit);
// a dump's samples against the density it claims (validate_sample_file, streamed, on the root); either against
// the visible normals traced on a tile (its rays split like a VNDF's, the samples compared on the root).
// Cancelled: nothing is kept (the validator has no partial result), it runs again on resumption.
#include "experiment/plan_kinds.h"
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
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
    const auto bins = claimed_reference_bins(*sampler, ggx(), view(), quantity_.rows);
    return validation_part(task, mine, own_tally(*sampler, *bins, options, mine));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const SamplerInfo* sampler = find_sampler(quantity_.sampler);
    if (sampler == nullptr)
      throw std::invalid_argument(fmt::format("{}.sampler: unknown sampler '{}'", quantity_.key, quantity_.sampler));
    const ValidationOptions v =
        validation_request(quantity_, first_units(decision_, c.options.cost_factor), c.round_seed(0), c.options.run);
    m.rounds.clear();
    m.partial = false;
    const auto clock = std::chrono::steady_clock::now();
    ValidationReport r;
    try {
      r = split_validation(c.split(), c.index, *sampler, ggx(), view(), v);
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
    record(r, r.samples, seconds_since(clock), m);
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
    m.rounds.clear();
    m.partial = false;
    const auto clock = std::chrono::steady_clock::now();
    try {
      DirectionSampleReader reader = open_dump(q);
      ValidationReport r = validate_dump_as_given(reader, claims, ggx(), view(), v, q.dump_frame == "z-up");
      r.sampler = q.dump;
      record(r, decision_.units, seconds_since(clock), m);
    } catch (const Cancelled&) {
      m.partial = true;
    } catch (const SampleFileError& e) {
      rethrow_dump_error(e);
    } catch (const InsufficientData& e) {
      rethrow_dump_error(e);
    }
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
    } catch (const SampleFileError& e) {
      rethrow_dump_error(e);
    } catch (const InsufficientData& e) {
      if (q.dump.empty()) throw;
      rethrow_dump_error(e);
    }
  }
};


// ---- its plan ----------------------------------------------------------------------------------------------

// A dump's rows, read from the file (every row checked: a file that cannot be read as samples is bad input
// naming the spec's key, before anything runs). A second pass over the file, the run's being the first to test.
std::uint64_t dump_rows(const SpecQuantity& q, const RunControl& run) {
  try {
    DirectionSampleReader reader = open_dump(q);
    std::vector<Vec3<double>> block(kSampleFileBlock);
    std::vector<double> pdfs(reader.columns().has_pdf() ? block.size() : 0);
    std::vector<double> weights(block.size() * std::size_t(reader.columns().channels()));
    while (reader.read(block, pdfs, weights) > 0)
      if (run.cancelled()) throw Cancelled("plan: reading a dump");
    return reader.rows_read();
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

// A dump against its analytic reference: every row is tested, so the count is the file's rows and the TV they
// detect follows from it; detect_tv, when the spec gives one, is a target those rows meet or not.
void plan_dump_validation(const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = dump_rows(q, o.run);
  d.unit = "samples";
  const double detected = detectable_tv(d.units, tests.dof, tests.level, q.power);
  d.count_reason = fmt::format("the dump's {} rows (read from {}), all tested: they detect any deviation of TV {:.3g} "
                               "with power {} at level {:.3g} per binning (Sidak of {}), df {} (noncentrality >= 4 N "
                               "TV^2)", d.units, std::filesystem::path(q.dump).filename().string(), detected, q.power,
                               tests.level, q.significance, tests.dof);
  if (q.target > 0) {
    const std::uint64_t needed = validation_samples(q.target, tests.dof, tests.level, q.power);
    d.count_reason += fmt::format("; detect_tv {} needs {} rows: {}", q.target, needed,
                                  d.units >= needed ? "the dump has them" : "the dump has fewer (target not met)");
  } else {
    d.count_reason += "; no detect_tv asked: the rows fix the TV detected";
  }
  d.runnable = true;
}

void plan_validation_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  if (!q.dump.empty()) return plan_dump_validation(q, o, d);
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = validation_samples(q.target, tests.dof, tests.level, q.power);
  d.unit = "samples";
  d.count_reason = fmt::format("chi-square power: df {}, level {:.3g} per binning (Sidak of {}), power {} against any "
                               "deviation of TV {} (noncentrality >= 4 N TV^2)", tests.dof, tests.level, q.significance,
                               q.power, q.target);
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
  d.units = std::max(2 * validation_samples(q.target, tests.dof, tests.level, q.power), minimum);
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

void plan_validation_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                              std::vector<Decision>& out) {
  plan_views(spec, index, o, cache, {plan_validation_view, plan_heightfield_validation, surface_validation_refusal}, out);
}

std::unique_ptr<Measurement> make_validation_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::heightfield) return std::make_unique<TileValidation>(spec, decision);
  if (!spec.quantities.at(decision.quantity).dump.empty()) return std::make_unique<DumpValidation>(spec, decision);
  return std::make_unique<DrawnValidation>(spec, decision);
}

}  // namespace microsim::experiment
