// experiment: the spec's identity (spec.h): its canonical description and digest, and the masking `what` text.
#include "experiment/spec_tree.h"

#include "core/fnv1a.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::experiment {

std::string to_string(const MaskingWhat& what) {
  std::vector<std::string> names;
  if (what.g1) names.push_back("g1");
  if (what.g2) names.push_back("g2");
  if (what.conditional) names.push_back("conditional");
  return fmt::format("{}", fmt::join(names, ", "));
}

std::string canonical_spec(const ExperimentSpec& spec) {
  nlohmann::json j;
  j["name"] = spec.name;
  j["seed"] = spec.seed;
  for (const SpecMaterial& m : spec.materials)
    j["materials"].push_back({{"name", m.name}, {"ndf", to_string(m.ndf)}, {"alphas", m.alphas}, {"facet", m.facet.describe()}});
  for (const SpecQuantity& q : spec.quantities) {
    nlohmann::json d = nlohmann::json::array();
    for (const Direction& v : q.directions) d.push_back({v.theta_deg, v.phi_deg});
    j["quantities"].push_back({{"kind", to_string(q.kind)}, {"material", q.material}, {"orders", to_string(q.orders)},
                               {"target", q.target}, {"directions", d}, {"surface", q.surface.name},
                               {"mus", q.mus}, {"inside", q.inside}, {"rows", q.rows}, {"sampler", q.sampler},
                               {"power", q.power}, {"significance", q.significance}});
    if (const auto kind_canonical = kind_spec(q.kind).canonical) j["quantities"].back().update(kind_canonical(q));
    if (!q.settings.empty()) j["quantities"].back()["settings"] = q.settings;  // none: the digests of earlier specs
  }
  return j.dump();
}

std::string spec_digest(const ExperimentSpec& spec) {
  return fmt::format("{:016x}", fnv1a(canonical_spec(spec)));  // an identity check of a directory's results
}

}  // namespace microsim::experiment
