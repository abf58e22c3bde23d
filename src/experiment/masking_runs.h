// experiment: a masking decision's view as measure/masking_runs.h measures it (kind = "masking": Smith's closed
// forms, or its explicit surface traced in rounds).
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


}  // namespace microsim::experiment
