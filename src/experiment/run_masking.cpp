// experiment: a masking decision's rounds (masking_runs.h: run_masking).
#include "experiment/masking_runs.h"
#include "core/wall_clock.h"
#include "experiment/masking_surface.h"
#include "experiment/split_rounds.h"

#include <chrono>

namespace microsim::experiment {
namespace {

// The closed forms, once (deterministic: resumed, computed again).
void run_analytic_masking(const ExperimentSpec& spec, MeasurementResult& m) {
  const SpecQuantity& q = spec.quantities[m.decision.quantity];
  const auto clock = std::chrono::steady_clock::now();
  m.rounds.clear();
  m.partial = false;
  m.values = analytic_masking_json(q, spec.material(q.material), m.decision);
  m.achieved = 0;
  m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), 0});
  m.met = true;
}

// Rounds of blocks until the target standard error is met (the completed rounds of an interrupted run are
// restored from m.values first).
void run_heightfield_rounds(HeightfieldMasking& h, std::uint64_t first_units, const RunOptions& o, const MaskingRound& round,
                            MeasurementResult& m) {
  if (!m.rounds.empty()) h.restore(m.values);
  m.partial = false;
  std::uint64_t n = m.rounds.empty() ? first_units : next_round_units(m.units, m.achieved, m.target);
  for (int r = int(m.rounds.size()); r < o.max_rounds && n > 0; ++r) {
    const auto clock = std::chrono::steady_clock::now();
    const std::uint64_t before = h.samples();
    const std::uint64_t end = h.blocks_done() + (n + kSamplesPerBlock - 1) / kSamplesPerBlock;
    if (!h.add_blocks(end, o.run, round)) {
      m.partial = true;
      break;
    }
    m.achieved = h.worst_standard_error();
    m.rounds.push_back({h.samples() - before, n, end, false, h.seed(), 0, seconds_since(clock), m.achieved});
    m.units = h.samples();
    m.rays = h.rays();
    m.values = h.values_json();
    n = next_round_units(m.units, m.achieved, m.target);
  }
  m.met = !m.rounds.empty() && !m.partial && m.achieved <= m.target;
}

}  // namespace

void run_masking(const ExperimentSpec& spec, std::size_t index, std::uint64_t seed, std::uint64_t sample_seed,
                 std::uint64_t first_units, const RunOptions& o, SurfaceCache& surfaces, MeasurementResult& m) {
  const Decision& d = m.decision;
  if (d.model.model == Model::analytic) return run_analytic_masking(spec, m);
  const SpecQuantity& q = spec.quantities[d.quantity];
  const SpecMaterial& material = spec.material(q.material);
  std::optional<HeightfieldMasking> h;
  try {
    h.emplace(q, d, acquire_masking_surface(q, material, d.alpha, seed, surfaces, o.run),
              masking_surface_text(q, material, d.alpha, seed), sample_seed);
  } catch (const Cancelled&) {
    m.partial = true;
    return;
  }
  run_heightfield_rounds(*h, first_units, o, [&](const BlockRange& blocks) {
    return split_masking_round({o.ranks, o.stored}, index, *h, seed, blocks, o.run);
  }, m);
}

}  // namespace microsim::experiment
