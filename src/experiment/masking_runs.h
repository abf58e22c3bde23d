// experiment: a masking decision's view as measure/masking_runs.h measures it (kind = "masking": Smith's closed
// forms, or its explicit surface traced in rounds), and the means over a quantity's realisations.
#pragma once

#include "experiment/plan.h"
#include "experiment/run.h"
#include "measure/masking_runs.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::experiment {

// What a masking decision measures of its view: its quantity's `what`, lights and bins.
MaskingView masking_view(const SpecQuantity& quantity, const Decision& decision);
// Smith's closed forms of a decision: analytic_masking_json of its view on its material's NDF at its alpha.
nlohmann::json analytic_masking_json(const SpecQuantity& quantity, const SpecMaterial& material, const Decision& decision);

// The traced measurement of a decision's view on `field` (the surface cache's, which outlives it).
class HeightfieldMasking : public MaskingRuns {
public:
  HeightfieldMasking(const SpecQuantity& quantity, const Decision& decision, const microgeom::Heightfield& field,
                     std::string surface_text, std::uint64_t seed)
      : MaskingRuns(masking_view(quantity, decision), field, std::move(surface_text), seed) {}
};

// Masking over several realisations (a quantity's `realisations` > 1): per quantity, alpha and view whose
// realisations ran whole (at least two; met or not, so that none is selected by its values), every measured
// value's mean over them with its standard error from their spread (sample standard deviation / sqrt(K): the
// realisations are independent surfaces, so it holds both the spread between surfaces and each one's Monte
// Carlo error) and the Monte Carlo part alone (the root mean square of their standard errors / sqrt(K)). An
// array of {"label", "realisations", "g1", "g2": [...], "conditional": {"by_normal": [...], "by_height": [...]}},
// each value {"mean", "standard_error", "monte_carlo_error"}; empty when no quantity has several.
nlohmann::json masking_realisation_means(const std::vector<MeasurementResult>& measurements);

}  // namespace microsim::experiment
