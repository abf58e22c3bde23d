// experiment: the VNDF kind (measurement.h): rounds of rays, each from its own seed, their exact counts summed;
// the TV the sum resolves (resolved_tv: its noise floor over kNoiseShare) decides against target_tv. On the
// ellipsoid oracle (Heitz 2018: a convex GGX ellipsoid's visible normals are D_v) or on an explicit tile
// (built once through the SurfaceCache). A cancelled round keeps its completed blocks (a shorter run of its
// seed), and a resumed run traces on from its first missing block: the counts of the uninterrupted run.
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "experiment/measures.h"

#include "core/errors.h"
#include "core/parse.h"
#include "core/wall_clock.h"

#include <fmt/core.h>

#include <chrono>

namespace microsim::experiment {
namespace {

// Adds a round's exact counts to the sum (the first round gives the binnings and attributes).
void add_vndf_counts(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const TracedHistogram& round,
                     const std::vector<std::uint64_t>& round_unbinned) {
  if (sum.binnings.empty()) {
    sum = round;
    unbinned = round_unbinned;
    return;
  }
  for (std::size_t k = 0; k < sum.counts.size(); ++k)
    for (std::size_t i = 0; i < sum.counts[k].size(); ++i) sum.counts[k][i] += round.counts[k][i];
  for (std::size_t k = 0; k < unbinned.size(); ++k) unbinned[k] += round_unbinned[k];
  sum.rays += round.rays;
  sum.hits += round.hits;
}

// A round's bookkeeping once its rays are added and the sum analysed (`achieved` set).
void record_vndf_round(MeasurementResult& m, const RoundStart& start, const TraceResult& trace, std::uint64_t rays,
                       double seconds) {
  m.units += rays;
  m.rays += rays;
  m.rounds.push_back({start.done + rays, start.units, trace.blocks.end, trace.partial, start.seed, 0, seconds, m.achieved});
}

class VndfMeasurement : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the TV the histogram resolves: its TV noise floor (expected TV of an exact sampler, largest "
                       "binning) over {}", kNoiseShare);
  }
  bool split() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    const std::uint64_t units = std::min(first_units(decision_, 1), kMaxRays);  // capped as the rounds cap them
    return {index, units, round_seed(seed, index, 0), BlockRange{0, BlockPlan{units, kRaysPerBlock}.blocks()}};
  }
};

// On the ellipsoid oracle.
class EllipsoidVndfMeasurement final : public VndfMeasurement {
public:
  using VndfMeasurement::VndfMeasurement;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run, SurfaceCache&) const override {
    VndfRequest request = vndf_request(spec_, decision_, task.units, task.seed, run);
    request.blocks = mine;
    return vndf_part(measure_ellipsoid_vndf(target(decision_), request).trace, {});
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    run_histogram_rounds(c, m, kMaxRays, [&](const RoundStart& start) { return round(c, start, m); });
  }

private:
  static EllipsoidTarget target(const Decision& d) { return EllipsoidTarget(d.alpha.first, d.alpha.second, -1); }
  // One round (or the rest of one): traced, added to the sum, the sum analysed and recorded.
  bool round(const RoundContext& c, const RoundStart& start, MeasurementResult& m) const {
    VndfRequest req = vndf_request(spec_, decision_, start.units, start.seed, c.options.run);
    if (const auto blocks = start.blocks(kRaysPerBlock)) req.blocks = *blocks;
    const auto clock = std::chrono::steady_clock::now();
    const EllipsoidVndf r = split_vndf_round(c.split(), c.index, target(decision_), req);
    m.partial = r.trace.partial;  // cancelled: its completed blocks are a shorter run of that seed, kept
    if (r.histogram.rays == 0) return false;
    const bool fresh = m.histogram.binnings.empty();
    add_vndf_counts(m.histogram, m.unbinned, r.histogram, r.trace.unbinned);
    // A whole first round: its own analysis is the sum's (the reference's cubature is not paid twice).
    const EllipsoidVndf analysed = fresh && !r.trace.partial ? r : analyse_ellipsoid_vndf(m.histogram, m.unbinned);
    m.achieved = resolved_tv(vndf_noise_floor(analysed));
    record_vndf_round(m, start, r.trace, r.histogram.rays, seconds_since(clock));
    m.values = {{"analysis", to_json(analysed.analysis)},
                {"rays", analysed.histogram.rays},
                {"hits", analysed.histogram.hits},
                {"expected_hit_fraction", r.expected_hit_fraction},
                {"total_variation", vndf_total_variation(analysed)},
                {"noise_floor_tv", vndf_noise_floor(analysed)},
                {"unbinned", m.unbinned}};
    m.histogram = analysed.histogram;
    return true;
  }
};

// On an explicit tile: every rank traces the same tile (its SurfaceCache's).
class HeightfieldVndfMeasurement final : public VndfMeasurement {
public:
  using VndfMeasurement::VndfMeasurement;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &decision_surface(decision_, surfaces, run);
    } catch (const Cancelled&) {
      return cancelled_part(mine);  // its build cancelled: a part cancelled before its first block
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
    // The scene is built when the root's own part begins: after the round was sent, while the ranks build theirs.
    const SceneOf scene = [&c, field]() -> const HeightfieldScene& { return c.surfaces.scene_for(*field); };
    run_histogram_rounds(c, m, kMaxRays, [&](const RoundStart& start) { return round(c, scene, *field, start, m); });
  }

private:
  bool round(const RoundContext& c, const SceneOf& scene, const microgeom::Heightfield& field, const RoundStart& start,
             MeasurementResult& m) const {
    VndfRequest req = vndf_request(spec_, decision_, start.units, start.seed, c.options.run);
    if (const auto blocks = start.blocks(kRaysPerBlock)) req.blocks = *blocks;
    const auto clock = std::chrono::steady_clock::now();
    const HeightfieldVndf r =
        split_heightfield_vndf_round(c.split(), c.index, scene, field, surface_label(decision_.surface), req);
    m.partial = r.trace.partial;
    if (r.histogram.rays == 0) return false;
    if (!m.histogram.binnings.empty()) add_heightfield_diagnostics(m.histogram, r.histogram);  // the analysis reads them
    add_vndf_counts(m.histogram, m.unbinned, r.histogram, r.trace.unbinned);
    const HeightfieldVndf analysed = analyse_heightfield_vndf(m.histogram, m.unbinned, field);  // the sum so far
    m.achieved = resolved_tv(heightfield_noise_floor(analysed));
    record_vndf_round(m, start, r.trace, r.histogram.rays, seconds_since(clock));
    m.values = heightfield_vndf_values(analysed, m.unbinned, decision_.surface);
    m.histogram = analysed.histogram;
    return true;
  }
};

}  // namespace

std::unique_ptr<Measurement> make_vndf_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::heightfield) return std::make_unique<HeightfieldVndfMeasurement>(spec, decision);
  return std::make_unique<EllipsoidVndfMeasurement>(spec, decision);
}

}  // namespace microsim::experiment
