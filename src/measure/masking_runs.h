// measure: the masking of one view of an explicit surface measured in rounds to a target standard error (an
// experiment's masking quantity on a heightfield), and Smith's closed forms for the same view:
//   analytic     G1(v) = 1 / (1 + Lambda(v))                (Heitz 2014, JCGT 3(2), eq. 43, the Smith masking of
//                                                           a front-facing m)
//                G2(v, l) = 1 / (1 + Lambda(v) + Lambda(l))  (eq. 99, height-correlated, reflection)
//                G1(v) G1(l)                                 (eq. 98, separable: reported beside it)
//                with Lambda of GGX (eq. 86) or Beckmann (Walter et al. 2007 eq. 27), from AnalyticSmith
//                (trace/smith_prediction.h). Exact: no noise, no surface;
//   traced       trace/masking.h's estimators on an explicit surface, by measure_masking (masking.h) over
//                successive block ranges [0, b1), [b1, b2), ... of ONE seed: a round adds the blocks a count
//                rule asks for, and the pooled estimate is that of the prefix [0, b) of one run (its exact sums
//                added: the same bits however the rounds split it). Per light one measure_masking call (the
//                same points; the pair G2 is the light's); G1 and the conditional bins from the first. Beside
//                each value: Smith's prediction with the analytic NDF (the surface's metadata) and with the
//                surface's own NDF, and the measured-minus-Smith difference with its standard error (Smith's
//                value is exact).
// The error of a masking view is the absolute standard error of every value measured: G1, each G2, and each
// conditional G1(v | bin) (bins of <v, m> and of height).
#pragma once

#include "measure/masking.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace microsim {

// The samples of a masking round are drawn in blocks of kSamplesPerBlock (trace/masking.h) from one run of
// this many samples: any prefix of its blocks is a run of its own.
inline constexpr std::uint64_t kMaskingRunSamples = kSamplesPerBlock << 28;
// Blocks of a masking pilot (planned counts; the pilot's samples are not in the results).
inline constexpr std::uint64_t kMaskingPilotBlocks = 16;

// What is measured of one view: G1(v), G2(v, l) for each light, G1(v | bin) in `bins` bins of <v, m> and of height.
struct MaskingView {
  double theta_deg = 0, phi_deg = 0;
  std::vector<std::pair<double, double>> lights;  // (theta, phi) in degrees, with g2
  bool g1 = false, g2 = false, conditional = false;
  int bins = 10;
};

// Smith's closed forms of a view on an `ndf` surface at `alpha`: {"masking": {"model": "analytic", "ndf",
// "alpha", "view", "lambda", "g1": {...}, "g2": [{"light", "value", "separable", ...}]}}, every standard error 0.
nlohmann::json analytic_masking_json(const MaskingView& view, NdfKind ndf, std::pair<double, double> alpha);

// The largest standard error of the wanted values of one result (G1, the pair G2, the conditional bins).
double masking_worst_standard_error(const MaskingView& view, const MaskingResult& result);

// A round's measurement of some blocks for every light (one SurfaceMasking per light, in call order, its
// sums exact): this process's (MaskingRuns::measure_round) or that of several processes combined.
// nullopt: cancelled (nothing of the round is kept).
using MaskingRound = std::function<std::optional<std::vector<SurfaceMasking>>(const BlockRange& blocks)>;

// The traced measurement of one view: its surface (`field`, which must outlive it), its scene, and the exact
// sums of the blocks [0, blocks_done()) of `seed` per light (one when the view has no G2).
class MaskingRuns {
public:
  MaskingRuns(MaskingView view, const microgeom::Heightfield& field, std::string surface_text, std::uint64_t seed);
  MaskingRuns(const MaskingRuns&) = delete;
  MaskingRuns& operator=(const MaskingRuns&) = delete;

  // Samples blocks [blocks_done(), end) for every light (by `round`; empty: measure_round here) and adds them.
  // False (nothing added) when cancelled.
  bool add_blocks(std::uint64_t end, const RunControl& run, const MaskingRound& round = {});
  // This process's measurement of `blocks` for every light; nullopt when cancelled.
  std::optional<std::vector<SurfaceMasking>> measure_round(const BlockRange& blocks, const RunControl& run) const;
  std::uint64_t seed() const { return seed_; }
  std::uint64_t blocks_done() const { return blocks_done_; }
  std::uint64_t samples() const { return blocks_done_ * kSamplesPerBlock; }
  std::uint64_t rays() const { return rays_; }
  double seconds() const { return seconds_; }
  // The estimates of blocks [0, blocks_done()) per light. Needs blocks_done() > 0.
  std::vector<MaskingResult> results() const;
  // The largest standard error of the values the view asks for (G1, G2 per light, conditional bins).
  double worst_standard_error() const;
  // {"masking": {...}} with the values, Smith's predictions, the differences, and "parts": the exact sums
  // per light (masking_part_json), from which restore() continues.
  nlohmann::json values_json() const;
  // The sums of values_json()'s "parts" (a resumed run). Throws std::invalid_argument when they are not this
  // measurement's (lights, seed, blocks).
  void restore(const nlohmann::json& values);

private:
  MaskingRequest request(std::size_t light, const BlockRange& blocks, const RunControl& run) const;
  MaskingView view_;
  const microgeom::Heightfield& field_;
  std::string surface_text_;
  std::unique_ptr<MaskingSurface> surface_;
  std::uint64_t seed_ = 0, blocks_done_ = 0, rays_ = 0;
  double seconds_ = 0;
  std::vector<SurfaceMasking> parts_;  // per light: the run's parameters and provenance, the summed sums
};

}  // namespace microsim
