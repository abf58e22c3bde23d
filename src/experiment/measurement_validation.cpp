// experiment: the validation kind (measurement.h): one chi-square validation at the planned sample count (the
// power rule needs no rounds, plan.h validation_samples). A zoo sampler's samples drawn against its claimed
// pdf (the ranks tally shards of the samples' blocks, merged in order: validate_sampler's report, bit for bit);
// a dump's samples against the density it claims (validate_sample_file, streamed, on the root); either against
// the visible normals traced on a tile (its rays split like a VNDF's, the samples compared on the root).
// Cancelled: nothing is kept (the validator has no partial result), it runs again on resumption.
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
    const std::uint64_t units = first_units(decision_, 1);
    return {index, units, round_seed(seed, index, 0), BlockRange{0, BlockPlan{units, kSampleBlock}.blocks()}};
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
    return validation_part(mine, own_tally(*sampler, *bins, options, mine));
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

// A dump: every sample of the file against the density it claims. A file that cannot be read, or holds too few
// samples, is bad input (std::invalid_argument naming the spec key). Not shared: the root reads the file.
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
    const ValidationOptions v = validation_request(q, 0, 0, c.options.run);
    m.rounds.clear();
    m.partial = false;
    const auto clock = std::chrono::steady_clock::now();
    const ClaimedDensity density = claimed_density(parse_file_pdf(q.dump_pdf), ggx(), view());
    const auto reference = q.above_horizon ? above_horizon_reference(density, ggx(), view(), q.rows)
                                           : density_reference(density, ggx(), view(), q.rows);
    try {
      DirectionSampleReader reader{std::filesystem::path(q.dump)};
      ValidationReport r = validate_sample_file(reader, density.domain, ggx(), view(), v, reference);
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

// Against the tile's traced visible normals (plan.cpp plan_heightfield_validation): the planned rays traced in
// one round of round seed 1 (split like a VNDF's), then the sampler's samples (drawn as validate_sampler draws
// them, from round seed 0) or the dump's against them on the root (validate/compare.h).
class TileValidation final : public ValidationMeasurement {
public:
  using ValidationMeasurement::ValidationMeasurement;
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    const std::uint64_t units = first_units(decision_, 1);
    return {index, units, round_seed(seed, index, 1), BlockRange{0, BlockPlan{units, kRaysPerBlock}.blocks()}};
  }
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &decision_surface(decision_, surfaces, run);
    } catch (const Cancelled&) {
      return cancelled_part(mine);
    }
    VndfRequest request = vndf_request(spec_, decision_, task.units, task.seed, run);
    request.blocks = mine;
    const HeightfieldVndf m = trace_heightfield_vndf(surfaces.scene_for(*field), *field, surface_label(decision_.surface), request);
    return vndf_part(m.trace, m.diagnostics);
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    m.partial = false;
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &decision_surface(decision_, c.surfaces, c.options.run);
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
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
        DirectionSampleReader reader{std::filesystem::path(q.dump)};
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

}  // namespace

std::unique_ptr<Measurement> make_validation_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::heightfield) return std::make_unique<TileValidation>(spec, decision);
  if (!spec.quantities.at(decision.quantity).dump.empty()) return std::make_unique<DumpValidation>(spec, decision);
  return std::make_unique<DrawnValidation>(spec, decision);
}

}  // namespace microsim::experiment
