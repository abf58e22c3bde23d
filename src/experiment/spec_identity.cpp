// experiment: the spec's identity (spec.h): its canonical description and digest, and the masking `what` text.
#include "experiment/spec.h"

#include "core/fnv1a.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::experiment {

namespace {
nlohmann::json masking_canonical(const SpecQuantity& q) {
  nlohmann::json lights = nlohmann::json::array();
  for (const Direction& l : q.lights) lights.push_back({l.theta_deg, l.phi_deg});
  nlohmann::json j{{"what", to_string(q.masking)}, {"lights", lights}, {"bins", q.bins}, {"resolution", q.resolution}};
  if (q.realisations > 1) j["realisations"] = q.realisations;  // one realisation: the digest of earlier versions
  return j;
}
}  // namespace

std::string to_string(const MaskingWhat& what) {
  std::vector<std::string> names;
  if (what.g1) names.push_back("g1");
  if (what.g2) names.push_back("g2");
  if (what.conditional) names.push_back("conditional");
  return fmt::format("{}", fmt::join(names, ", "));
}

namespace {
// A dump's keys; those beyond the first three only when not their defaults (the digests of earlier specs hold).
nlohmann::json dump_canonical(const SpecQuantity& q) {
  nlohmann::json j{{"dump", q.dump}, {"pdf", q.dump_pdf}, {"above_horizon", q.above_horizon}};
  if (q.dump_columns != "x,y,z") j["columns"] = q.dump_columns;
  if (q.dump_frame != "z-up") j["frame"] = q.dump_frame;
  if (q.dump_dropped != 0) j["dropped"] = q.dump_dropped;
  if (q.convention != BsdfConvention{}) j["convention"] = describe(q.convention);
  return j;
}
}  // namespace

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
    if (!q.dump.empty())  // the path names the dump: a file replaced under the same path is not detected
      j["quantities"].back().update(dump_canonical(q));
    if (q.kind == QuantityKind::masking) j["quantities"].back().update(masking_canonical(q));
  }
  return j.dump();
}

std::string spec_digest(const ExperimentSpec& spec) {
  return fmt::format("{:016x}", fnv1a(canonical_spec(spec)));  // an identity check of a directory's results
}

}  // namespace microsim::experiment
