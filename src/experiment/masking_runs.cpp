// experiment: the analytic and the heightfield masking measurements of a decision (masking_runs.h).
#include "experiment/masking_runs.h"

#include "core/math.h"

#include <fmt/core.h>
#include <cmath>
#include <map>

#include <algorithm>
#include <stdexcept>

namespace microsim::experiment {
namespace {

using nlohmann::json;

json masking_direction_json(const Direction& d) { return {{"theta_deg", d.theta_deg}, {"phi_deg", d.phi_deg}}; }

Vec3<double> masking_unit(const Direction& d) { return direction_from_degrees(d.theta_deg, d.phi_deg); }

// The lights of a quantity's measurement calls: its lights with g2, else one call without a light.
std::vector<std::optional<Direction>> masking_call_lights(const SpecQuantity& q) {
  std::vector<std::optional<Direction>> out;
  if (q.masking.g2)
    for (const Direction& l : q.lights) out.emplace_back(l);
  if (out.empty()) out.emplace_back(std::nullopt);
  return out;
}

// A measured value beside Smith's predictions (analytic NDF, the surface's own NDF): the value, its standard
// error, and measured minus Smith with that error (Smith's values are exact).
json masking_compared_json(const Estimate& measured, double smith_analytic, double smith_own) {
  return {{"value", measured.value},
          {"standard_error", measured.standard_error},
          {"smith_analytic", smith_analytic},
          {"smith_own_ndf", smith_own},
          {"difference", {{"value", measured.value - smith_analytic}, {"standard_error", measured.standard_error}}},
          {"difference_own_ndf", {{"value", measured.value - smith_own}, {"standard_error", measured.standard_error}}}};
}

json masking_bins_json(const std::vector<ConditionalBin>& bins) {
  json out = json::array();
  for (const ConditionalBin& b : bins) {
    json j = masking_compared_json(b.g1, b.smith_analytic, b.smith_empirical);
    j.update({{"lo", b.lo}, {"hi", b.hi}, {"share", b.share}, {"samples", b.samples}});
    out.push_back(std::move(j));
  }
  return out;
}

json masking_g2_json(const Direction& light, const G2Result& g) {
  json j = masking_compared_json(g.value, g.smith_analytic, g.smith_empirical);
  j.update({{"light", masking_direction_json(light)}, {"samples", g.samples}, {"separable_analytic", g.separable_analytic}});
  return j;
}

}  // namespace

AnalyticSmith analytic_smith(const SpecMaterial& m, std::pair<double, double> alpha) {
  return AnalyticSmith(m.ndf, alpha.first, alpha.second);
}

json analytic_masking_json(const SpecQuantity& q, const SpecMaterial& m, const Decision& d) {
  const AnalyticSmith smith = analytic_smith(m, d.alpha);
  const Vec3<double> v = masking_unit(d.view);
  json out = {{"model", "analytic"}, {"ndf", to_string(smith.ndf())}, {"alpha", {d.alpha.first, d.alpha.second}},
              {"view", masking_direction_json(d.view)}, {"lambda", smith.Lambda(v)}};
  if (q.masking.g1) out["g1"] = {{"value", smith.G1(v)}, {"standard_error", 0.0}, {"smith_analytic", smith.G1(v)}};
  if (q.masking.g2) {
    out["g2"] = json::array();
    for (const Direction& l : q.lights)
      out["g2"].push_back({{"light", masking_direction_json(l)}, {"value", smith.G2(v, masking_unit(l))}, {"standard_error", 0.0},
                           {"smith_analytic", smith.G2(v, masking_unit(l))}, {"separable_analytic", smith.G2_separable(v, masking_unit(l))},
                           {"lambda_light", smith.Lambda(masking_unit(l))}});
  }
  return {{"masking", out}};
}

double masking_worst_standard_error(const SpecQuantity& q, const MaskingResult& r) {
  double worst = 0;
  if (q.masking.g1) worst = std::max(worst, r.g1.standard_error);
  if (q.masking.g2 && r.pair) worst = std::max(worst, r.pair->value.standard_error);
  if (q.masking.conditional) {
    for (const ConditionalBin& b : r.by_normal) worst = std::max(worst, b.g1.standard_error);
    for (const ConditionalBin& b : r.by_height) worst = std::max(worst, b.g1.standard_error);
  }
  return worst;
}

// ---- the heightfield ------------------------------------------------------------------------------------------

HeightfieldMasking::HeightfieldMasking(const SpecQuantity& q, const Decision& d, const microgeom::Heightfield& field,
                                       std::string surface_text, std::uint64_t seed)
    : quantity_(q), decision_(d), field_(field), surface_text_(std::move(surface_text)),
      surface_(std::make_unique<MaskingSurface>(field_, surface_text_, HeightfieldGeometry::triangles, true)),
      seed_(seed) {}

MaskingRequest HeightfieldMasking::request(std::size_t light, const BlockRange& blocks, const RunControl& run) const {
  MaskingRequest r;
  r.theta_deg = decision_.view.theta_deg;
  r.phi_deg = decision_.view.phi_deg;
  if (const auto l = masking_call_lights(quantity_)[light]) {
    r.theta_l_deg = l->theta_deg;
    r.phi_l_deg = l->phi_deg;
  }
  r.samples = kMaskingRunSamples;
  r.seed = seed_;
  r.bins = quantity_.bins;
  r.blocks = blocks;
  r.run = run;
  return r;
}

std::optional<std::vector<SurfaceMasking>> HeightfieldMasking::measure_round(const BlockRange& blocks,
                                                                             const RunControl& run) const {
  std::vector<SurfaceMasking> round;
  for (std::size_t k = 0; k < masking_call_lights(quantity_).size(); ++k) {
    if (run.cancelled()) return std::nullopt;
    round.push_back(measure_masking(*surface_, request(k, blocks, run)));
    if (round.back().result.partial) return std::nullopt;
  }
  return round;
}

bool HeightfieldMasking::add_blocks(std::uint64_t end, const RunControl& run, const MaskingRound& measure) {
  if (end <= blocks_done_) return true;
  const BlockRange blocks{blocks_done_, end};
  std::optional<std::vector<SurfaceMasking>> round = measure ? measure(blocks) : measure_round(blocks, run);
  if (!round) return false;
  for (std::size_t k = 0; k < round->size(); ++k) {
    SurfaceMasking& r = (*round)[k];
    rays_ += r.result.rays;
    seconds_ += r.result.seconds;
    if (parts_.size() <= k) {
      parts_.push_back(std::move(r));
    } else {
      parts_[k].result.sums += r.result.sums;
      parts_[k].provenance.blocks.end = end;
    }
  }
  blocks_done_ = end;
  return true;
}

std::vector<MaskingResult> HeightfieldMasking::results() const {
  if (blocks_done_ == 0) throw std::logic_error("HeightfieldMasking::results: no blocks sampled");
  std::vector<MaskingResult> out;
  for (std::size_t k = 0; k < parts_.size(); ++k) {
    const MaskingRequest r = request(k, BlockRange{blocks_done_, blocks_done_}, RunControl{});
    MaskingOptions o = masking_options(r);
    o.blocks.reset();  // the sums are of blocks [0, blocks_done_), passed below
    out.push_back(masking_result_from_sums(field_, surface_->analytic, surface_->empirical,
                                           direction_from_degrees(r.theta_deg, r.phi_deg), o, parts_[k].result.sums,
                                           BlockRange{0, blocks_done_}));
  }
  return out;
}

double HeightfieldMasking::worst_standard_error() const {
  double worst = 0;
  for (const MaskingResult& r : results()) worst = std::max(worst, masking_worst_standard_error(quantity_, r));
  return worst;
}

json HeightfieldMasking::values_json() const {
  const std::vector<MaskingResult> r = results();
  const MaskingResult& first = r.front();
  json out = {{"model", "heightfield"}, {"surface", surface_text_},
              {"reference", surface_->analytic.describe() + " (" + surface_->reference_source + ")"},
              {"view", masking_direction_json(decision_.view)}, {"seed", seed_}, {"samples", samples()},
              {"blocks", {0, blocks_done_}}, {"rays", rays_}, {"seconds", seconds_},
              {"leak_ratio", {{"value", first.leak_ratio.value}, {"standard_error", first.leak_ratio.standard_error}}}};
  if (quantity_.masking.g1) out["g1"] = masking_compared_json(first.g1, first.g1_smith_analytic, first.g1_smith_empirical);
  if (quantity_.masking.g2) {
    out["g2"] = json::array();
    for (std::size_t k = 0; k < r.size(); ++k) out["g2"].push_back(masking_g2_json(quantity_.lights.at(k), r[k].pair.value()));
  }
  if (quantity_.masking.conditional)
    out["conditional"] = {{"by_normal", masking_bins_json(first.by_normal)}, {"by_height", masking_bins_json(first.by_height)}};
  out["parts"] = json::array();
  for (const SurfaceMasking& p : parts_) out["parts"].push_back(masking_part_json(p));
  return {{"masking", out}};
}

void HeightfieldMasking::restore(const json& values) {
  const json& parts = values.at("masking").at("parts");
  if (!parts.is_array() || parts.size() != masking_call_lights(quantity_).size())
    throw std::invalid_argument("results.json: a masking measurement's parts are not one per light");
  std::vector<SurfaceMasking> restored;
  for (const json& j : parts) {
    MaskingPart p;
    try {
      p = read_masking_part(j);
    } catch (const std::exception& e) {
      throw std::invalid_argument(fmt::format("results.json: a masking measurement's part: {}", e.what()));
    }
    if (p.provenance.seed != seed_ || p.provenance.blocks.begin != 0 ||
        (!restored.empty() && p.provenance.blocks.end != restored.front().provenance.blocks.end))
      throw std::invalid_argument("results.json: a masking measurement's parts are not blocks [0, B) of its seed");
    SurfaceMasking s;
    s.parameters = p.parameters;
    s.provenance = p.provenance;
    s.result.sums = p.sums;
    restored.push_back(std::move(s));
  }
  parts_ = std::move(restored);
  blocks_done_ = parts_.front().provenance.blocks.end;
  rays_ = values["masking"].value("rays", std::uint64_t(0));
  seconds_ = values["masking"].value("seconds", 0.0);
}

namespace {

// The mean of one value over realisations ({"value", "standard_error"} each).
nlohmann::json realisation_mean(const std::vector<const nlohmann::json*>& values) {
  const double k = double(values.size());
  double sum = 0, mc = 0;
  for (const nlohmann::json* v : values) {
    sum += v->at("value").get<double>();
    mc += std::pow(v->at("standard_error").get<double>(), 2);
  }
  const double mean = sum / k;
  double spread = 0;
  for (const nlohmann::json* v : values) spread += std::pow(v->at("value").get<double>() - mean, 2);
  return {{"mean", mean}, {"standard_error", std::sqrt(spread / (k - 1) / k)}, {"monte_carlo_error", std::sqrt(mc) / k}};
}

// The same member of every realisation's masking values, by a path of keys and indices.
nlohmann::json mean_of(const std::vector<const nlohmann::json*>& maskings, const nlohmann::json::json_pointer& where) {
  std::vector<const nlohmann::json*> values;
  for (const nlohmann::json* mk : maskings) values.push_back(&mk->at(where));
  return realisation_mean(values);
}

nlohmann::json group_means(const std::string& label, const std::vector<const nlohmann::json*>& maskings) {
  using ptr = nlohmann::json::json_pointer;
  const nlohmann::json& first = *maskings.front();
  nlohmann::json out{{"label", label}, {"realisations", maskings.size()}, {"g1", mean_of(maskings, ptr("/g1"))}};
  if (first.contains("g2")) {
    out["g2"] = nlohmann::json::array();
    for (std::size_t l = 0; l < first["g2"].size(); ++l) {
      nlohmann::json g2 = mean_of(maskings, ptr(fmt::format("/g2/{}", l)));
      g2["light"] = first["g2"][l]["light"];
      out["g2"].push_back(g2);
    }
  }
  if (first.contains("conditional"))
    for (const char* binning : {"by_normal", "by_height"}) {
      out["conditional"][binning] = nlohmann::json::array();
      for (std::size_t b = 0; b < first["conditional"][binning].size(); ++b)
        out["conditional"][binning].push_back(mean_of(maskings, ptr(fmt::format("/conditional/{}/{}", binning, b))));
    }
  return out;
}

}  // namespace

nlohmann::json masking_realisation_means(const std::vector<MeasurementResult>& measurements) {
  std::map<std::string, std::vector<const nlohmann::json*>> groups;  // by label without " realisation k"
  std::vector<std::string> order;
  for (const MeasurementResult& m : measurements) {
    const Decision& d = m.decision;
    if (!m.ran || m.partial || d.model.model != Model::heightfield || !m.values.contains("masking")) continue;
    const std::string label = d.label.substr(0, d.label.rfind(" realisation "));
    if (label.size() == d.label.size()) continue;  // one realisation
    if (groups[label].empty()) order.push_back(label);
    groups[label].push_back(&m.values.at("masking"));
  }
  nlohmann::json out = nlohmann::json::array();
  for (const std::string& label : order)
    if (groups[label].size() >= 2) out.push_back(group_means(label, groups[label]));
  return out;
}

}  // namespace microsim::experiment
