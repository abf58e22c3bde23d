// measure: the masking of one view in rounds, and Smith's closed forms (masking_runs.h).
#include "measure/masking_runs.h"

#include "core/math.h"

#include <fmt/core.h>
#include <cmath>
#include <map>

#include <algorithm>
#include <stdexcept>

namespace microsim {
namespace {

using nlohmann::json;

using Degrees = std::pair<double, double>;  // (theta, phi)

json masking_direction_json(const Degrees& d) { return {{"theta_deg", d.first}, {"phi_deg", d.second}}; }

Vec3<double> masking_unit(const Degrees& d) { return direction_from_degrees(d.first, d.second); }

// The lights of a view's measurement calls: its lights with g2, else one call without a light.
std::vector<std::optional<Degrees>> masking_call_lights(const MaskingView& v) {
  std::vector<std::optional<Degrees>> out;
  if (v.g2)
    for (const Degrees& l : v.lights) out.emplace_back(l);
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

json masking_g2_json(const Degrees& light, const G2Result& g) {
  json j = masking_compared_json(g.value, g.smith_analytic, g.smith_empirical);
  j.update({{"light", masking_direction_json(light)}, {"samples", g.samples}, {"separable_analytic", g.separable_analytic}});
  return j;
}

}  // namespace

json analytic_masking_json(const MaskingView& view, NdfKind ndf, std::pair<double, double> alpha) {
  const AnalyticSmith smith(ndf, alpha.first, alpha.second);
  const Degrees at{view.theta_deg, view.phi_deg};
  const Vec3<double> v = masking_unit(at);
  json out = {{"model", "analytic"}, {"ndf", to_string(smith.ndf())}, {"alpha", {alpha.first, alpha.second}},
              {"view", masking_direction_json(at)}, {"lambda", smith.Lambda(v)}};
  if (view.g1) out["g1"] = {{"value", smith.G1(v)}, {"standard_error", 0.0}, {"smith_analytic", smith.G1(v)}};
  if (view.g2) {
    out["g2"] = json::array();
    for (const Degrees& l : view.lights)
      out["g2"].push_back({{"light", masking_direction_json(l)}, {"value", smith.G2(v, masking_unit(l))}, {"standard_error", 0.0},
                           {"smith_analytic", smith.G2(v, masking_unit(l))}, {"separable_analytic", smith.G2_separable(v, masking_unit(l))},
                           {"lambda_light", smith.Lambda(masking_unit(l))}});
  }
  return {{"masking", out}};
}

double masking_worst_standard_error(const MaskingView& v, const MaskingResult& r) {
  double worst = 0;
  if (v.g1) worst = std::max(worst, r.g1.standard_error);
  if (v.g2 && r.pair) worst = std::max(worst, r.pair->value.standard_error);
  if (v.conditional) {
    for (const ConditionalBin& b : r.by_normal) worst = std::max(worst, b.g1.standard_error);
    for (const ConditionalBin& b : r.by_height) worst = std::max(worst, b.g1.standard_error);
  }
  return worst;
}

// ---- traced ---------------------------------------------------------------------------------------------------

MaskingRuns::MaskingRuns(MaskingView view, const microgeom::Heightfield& field, std::string surface_text,
                         std::uint64_t seed)
    : view_(std::move(view)), field_(field), surface_text_(std::move(surface_text)),
      surface_(std::make_unique<MaskingSurface>(field_, surface_text_, HeightfieldGeometry::triangles, true)),
      seed_(seed) {}

MaskingRequest MaskingRuns::request(std::size_t light, const BlockRange& blocks, const RunControl& run) const {
  MaskingRequest r;
  r.theta_deg = view_.theta_deg;
  r.phi_deg = view_.phi_deg;
  if (const auto l = masking_call_lights(view_)[light]) {
    r.theta_l_deg = l->first;
    r.phi_l_deg = l->second;
  }
  r.samples = kMaskingRunSamples;
  r.seed = seed_;
  r.bins = view_.bins;
  r.blocks = blocks;
  r.run = run;
  return r;
}

std::optional<std::vector<SurfaceMasking>> MaskingRuns::measure_round(const BlockRange& blocks,
                                                                             const RunControl& run) const {
  std::vector<SurfaceMasking> round;
  for (std::size_t k = 0; k < masking_call_lights(view_).size(); ++k) {
    if (run.cancelled()) return std::nullopt;
    round.push_back(measure_masking(*surface_, request(k, blocks, run)));
    if (round.back().result.partial) return std::nullopt;
  }
  return round;
}

bool MaskingRuns::add_blocks(std::uint64_t end, const RunControl& run, const MaskingRound& measure) {
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

std::vector<MaskingResult> MaskingRuns::results() const {
  if (blocks_done_ == 0) throw std::logic_error("MaskingRuns::results: no blocks sampled");
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

double MaskingRuns::worst_standard_error() const {
  double worst = 0;
  for (const MaskingResult& r : results()) worst = std::max(worst, masking_worst_standard_error(view_, r));
  return worst;
}

json MaskingRuns::values_json() const {
  const std::vector<MaskingResult> r = results();
  const MaskingResult& first = r.front();
  json out = {{"model", "heightfield"}, {"surface", surface_text_},
              {"reference", surface_->analytic.describe() + " (" + surface_->reference_source + ")"},
              {"view", masking_direction_json({view_.theta_deg, view_.phi_deg})}, {"seed", seed_}, {"samples", samples()},
              {"blocks", {0, blocks_done_}}, {"rays", rays_}, {"seconds", seconds_},
              {"leak_ratio", {{"value", first.leak_ratio.value}, {"standard_error", first.leak_ratio.standard_error}}}};
  if (view_.g1) out["g1"] = masking_compared_json(first.g1, first.g1_smith_analytic, first.g1_smith_empirical);
  if (view_.g2) {
    out["g2"] = json::array();
    for (std::size_t k = 0; k < r.size(); ++k) out["g2"].push_back(masking_g2_json(view_.lights.at(k), r[k].pair.value()));
  }
  if (view_.conditional)
    out["conditional"] = {{"by_normal", masking_bins_json(first.by_normal)}, {"by_height", masking_bins_json(first.by_height)}};
  out["parts"] = json::array();
  for (const SurfaceMasking& p : parts_) out["parts"].push_back(masking_part_json(p));
  return {{"masking", out}};
}

void MaskingRuns::restore(const json& values) {
  const json& parts = values.at("masking").at("parts");
  if (!parts.is_array() || parts.size() != masking_call_lights(view_).size())
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

}  // namespace microsim
