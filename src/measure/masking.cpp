#include "measure/masking.h"

#include "core/strict_parse.h"
#include "measure/vndf.h"
#include "stats/part_json.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace microsim {

namespace {

constexpr const char* kMaskingProducer = "trace masking";

// ---- the run's parameters -----------------------------------------------------------------------------------

// FNV-1a (64 bits) of the height floats' bit patterns: the surface's identity in the parameters.
std::string surface_digest(const microgeom::Heightfield& field) {
  std::uint64_t h = 1469598103934665603ull;
  for (const float f : field.heights()) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    for (int k = 0; k < 4; ++k) {
      h ^= (bits >> (8 * k)) & 0xffu;
      h *= 1099511628211ull;
    }
  }
  return fmt::format("{:016x}", h);
}

// Everything that defines the run (not the seed, not the blocks, not the threads).
nlohmann::json masking_parameters(const MaskingSurface& surface, const MaskingRequest& r) {
  const microgeom::Heightfield& field = surface.field;
  return {{"surface", surface.path},
          {"surface_digest", surface_digest(field)},
          {"resolution", field.resolution()},
          {"tile_size", field.tile_size()},
          {"geometry", to_string(surface.geometry)},
          {"theta", r.theta_deg},
          {"phi", r.phi_deg},
          {"theta_l", r.theta_l_deg ? nlohmann::json(*r.theta_l_deg) : nlohmann::json(nullptr)},
          {"phi_l", r.phi_l_deg},
          {"cone_deg", r.cone_deg},
          {"samples", r.samples},
          {"bins", r.bins},
          {"grazing_share", r.grazing_share},
          {"block_size", kSamplesPerBlock}};
}

Vec3<double> masking_view(const MaskingRequest& r) { return direction_from_degrees(r.theta_deg, r.phi_deg); }

Provenance masking_provenance(const nlohmann::json& parameters, std::uint64_t seed, const MaskingResult& r) {
  Provenance p;
  p.producer = kMaskingProducer;
  p.measurement = parameters.dump();
  p.seed = seed;
  p.total_blocks = r.total_blocks;
  p.blocks = r.blocks;
  return p;
}

// ---- reading a part's JSON ----------------------------------------------------------------------------------

const PartReader kMaskingReader(kMaskingProducer);

[[noreturn]] void malformed(const std::string& where, const std::string& what) { kMaskingReader.malformed(where, what); }

// ---- exact sums as JSON -------------------------------------------------------------------------------------

std::string sum_hex(const ExactSum& s) { return fmt::format("{:016x}{:016x}", s.high_bits(), s.low_bits()); }

ExactSum sum_from_json(const nlohmann::json& v, const std::string& where) {
  const std::string text = v.is_string() ? v.get<std::string>() : std::string();
  const auto hex = [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); };
  if (text.size() != 32 || !std::all_of(text.begin(), text.end(), hex))
    malformed(where, fmt::format("= {} is not an exact sum (32 hex digits)", reader::quote_excerpt(v.dump())));
  return ExactSum::from_bits(std::stoull(text.substr(0, 16), nullptr, 16), std::stoull(text.substr(16), nullptr, 16));
}

ExactSum sum_member(const nlohmann::json& j, const char* key, const std::string& where) {
  return sum_from_json(kMaskingReader.member(j, key, where), where + "/" + key);
}

nlohmann::json sums_json(const std::vector<ExactSum>& sums) {
  nlohmann::json a = nlohmann::json::array();
  for (const ExactSum& s : sums) a.push_back(sum_hex(s));
  return a;
}

nlohmann::json ratio_json(const RatioTotals& t) {
  return {{"n", t.n}, {"x", sum_hex(t.x)}, {"y", sum_hex(t.y)}, {"xx", sum_hex(t.xx)}, {"yy", sum_hex(t.yy)},
          {"xy", sum_hex(t.xy)}};
}

RatioTotals ratio_from_json(const nlohmann::json& j, const std::string& where) {
  RatioTotals t;
  t.n = kMaskingReader.count(j, "n", where);
  t.x = sum_member(j, "x", where);
  t.y = sum_member(j, "y", where);
  t.xx = sum_member(j, "xx", where);
  t.yy = sum_member(j, "yy", where);
  t.xy = sum_member(j, "xy", where);
  return t;
}

nlohmann::json ratios_json(const std::vector<RatioTotals>& ts) {
  nlohmann::json a = nlohmann::json::array();
  for (const RatioTotals& t : ts) a.push_back(ratio_json(t));
  return a;
}

nlohmann::json g2_json(const G2Totals& g) {
  return {{"measured", ratio_json(g.measured)},          {"vs_analytic", ratio_json(g.vs_analytic)},
          {"vs_empirical", ratio_json(g.vs_empirical)},  {"pred_analytic", sum_hex(g.pred_analytic)},
          {"pred_empirical", sum_hex(g.pred_empirical)}, {"sep_analytic", sum_hex(g.sep_analytic)},
          {"sep_empirical", sum_hex(g.sep_empirical)}};
}

G2Totals g2_from_json(const nlohmann::json& j, const std::string& where) {
  G2Totals g;
  g.measured = ratio_from_json(kMaskingReader.member(j, "measured", where), where + "/measured");
  g.vs_analytic = ratio_from_json(kMaskingReader.member(j, "vs_analytic", where), where + "/vs_analytic");
  g.vs_empirical = ratio_from_json(kMaskingReader.member(j, "vs_empirical", where), where + "/vs_empirical");
  g.pred_analytic = sum_member(j, "pred_analytic", where);
  g.pred_empirical = sum_member(j, "pred_empirical", where);
  g.sep_analytic = sum_member(j, "sep_analytic", where);
  g.sep_empirical = sum_member(j, "sep_empirical", where);
  return g;
}

nlohmann::json masking_sums_json(const MaskingSums& s) {
  return {{"samples", s.samples},
          {"front", s.front},
          {"rays", s.rays},
          {"leaked", s.leaked},
          {"unresolved", s.unresolved},
          {"leak_y", sum_hex(s.leak_y)},
          {"leak_yy", sum_hex(s.leak_yy)},
          {"g1", ratio_json(s.g1)},
          {"near_grazing", ratio_json(s.near_grazing)},
          {"normal", ratios_json(s.normal)},
          {"height", ratios_json(s.height)},
          {"height_pred_analytic", sums_json(s.height_pred_analytic)},
          {"height_pred_empirical", sums_json(s.height_pred_empirical)},
          {"mirror", g2_json(s.mirror)},
          {"pair", g2_json(s.pair)},
          {"cone", g2_json(s.cone)}};
}

// An array member of `bins` elements, each read by `read`.
template <class T, class Read>
std::vector<T> array_member(const nlohmann::json& j, const char* key, std::size_t bins, const std::string& where,
                            Read read) {
  const nlohmann::json& a = kMaskingReader.member(j, key, where);
  if (!a.is_array() || a.size() != bins) malformed(where + "/" + key, fmt::format("is not an array of {} bins", bins));
  std::vector<T> out;
  for (std::size_t k = 0; k < a.size(); ++k) out.push_back(read(a[k], fmt::format("{}/{}/{}", where, key, k)));
  return out;
}

MaskingSums masking_sums_from_json(const nlohmann::json& j, std::size_t bins) {
  const std::string w = "sums";
  MaskingSums s;
  s.samples = kMaskingReader.count(j, "samples", w);
  s.front = kMaskingReader.count(j, "front", w);
  s.rays = kMaskingReader.count(j, "rays", w);
  s.leaked = kMaskingReader.count(j, "leaked", w);
  s.unresolved = kMaskingReader.count(j, "unresolved", w);
  s.leak_y = sum_member(j, "leak_y", w);
  s.leak_yy = sum_member(j, "leak_yy", w);
  s.g1 = ratio_from_json(kMaskingReader.member(j, "g1", w), w + "/g1");
  s.near_grazing = ratio_from_json(kMaskingReader.member(j, "near_grazing", w), w + "/near_grazing");
  s.normal = array_member<RatioTotals>(j, "normal", bins, w, ratio_from_json);
  s.height = array_member<RatioTotals>(j, "height", bins, w, ratio_from_json);
  s.height_pred_analytic = array_member<ExactSum>(j, "height_pred_analytic", bins, w, sum_from_json);
  s.height_pred_empirical = array_member<ExactSum>(j, "height_pred_empirical", bins, w, sum_from_json);
  s.mirror = g2_from_json(kMaskingReader.member(j, "mirror", w), w + "/mirror");
  s.pair = g2_from_json(kMaskingReader.member(j, "pair", w), w + "/pair");
  s.cone = g2_from_json(kMaskingReader.member(j, "cone", w), w + "/cone");
  return s;
}

// ---- the request of a part ----------------------------------------------------------------------------------

// The request the parameters describe (no blocks, no run control).
MaskingRequest request_from_parameters(const nlohmann::json& p, std::uint64_t seed) {
  const std::string w = "provenance/parameters";
  MaskingRequest r;
  r.theta_deg = kMaskingReader.real(p, "theta", w);
  r.phi_deg = kMaskingReader.real(p, "phi", w);
  if (!kMaskingReader.member(p, "theta_l", w).is_null()) r.theta_l_deg = kMaskingReader.real(p, "theta_l", w);
  r.phi_l_deg = kMaskingReader.real(p, "phi_l", w);
  r.cone_deg = kMaskingReader.real(p, "cone_deg", w);
  r.samples = kMaskingReader.count(p, "samples", w);
  r.bins = int(kMaskingReader.count(p, "bins", w));
  r.grazing_share = kMaskingReader.real(p, "grazing_share", w);
  r.seed = seed;
  return r;
}

}  // namespace

MaskingSurface::MaskingSurface(const microgeom::Heightfield& f, std::string p, HeightfieldGeometry g, bool trace)
    : field(f), path(std::move(p)), geometry(g), analytic(analytic_reference(f, &reference_source)), empirical(f),
      scene(trace ? std::make_unique<HeightfieldScene>(f, g) : nullptr) {}

SurfaceMasking measure_masking(const MaskingSurface& surface, const MaskingRequest& request) {
  if (!surface.scene) throw std::invalid_argument("measure_masking: the surface has no scene to trace");
  SurfaceMasking m;
  m.request = request;
  m.result = estimate_masking(*surface.scene, surface.analytic, surface.empirical, masking_view(request),
                              masking_options(request));
  m.parameters = masking_parameters(surface, request);
  m.provenance = masking_provenance(m.parameters, request.seed, m.result);
  return m;
}

MaskingVndf measure_masking_vndf(const MaskingSurface& surface, const MaskingRequest& request) {
  if (request.blocks)
    throw std::invalid_argument("measure_masking_vndf: the VNDF beside a masking run is not sharded (trace vndf --surface S --shard K/N is)");
  if (!surface.scene) throw std::invalid_argument("measure_masking_vndf: the surface has no scene to trace");
  const Vec3<double> v = masking_view(request);
  const std::vector<DirectionBinning> binnings = {
      DirectionBinning::sphere(2 * kMaskingVndfRows + 1),
      DirectionBinning::lobe(GGX<double>(surface.analytic.alpha_x(), surface.analytic.alpha_y()), v,
                             SampleDomain::microfacet_normal, kMaskingVndfRows)};
  TraceOptions to;
  to.rays = request.vndf_rays;
  to.seed = request.seed;
  to.run = request.run;
  MaskingVndf out;
  out.trace = trace_vndf_heightfield(*surface.scene, v, binnings, to, &out.diagnostics);
  for (std::size_t k = 0; k < binnings.size(); ++k)
    out.comparisons.push_back(compare_vndf(out.trace.counts[k], out.trace.unbinned[k], binnings[k], v, surface.analytic,
                                           surface.empirical));
  return out;
}

nlohmann::json masking_part_json(const SurfaceMasking& m) {
  nlohmann::json j;
  j["provenance"] = provenance_json(m.provenance, m.parameters);
  j["sums"] = masking_sums_json(m.result.sums);
  return j;
}

bool is_masking_part(const nlohmann::json& report) { return producer_of(report) == kMaskingProducer; }

MaskingPart read_masking_part(const nlohmann::json& report) {
  MaskingPart part;
  part.provenance = kMaskingReader.provenance(report, part.parameters);
  const std::uint64_t bins = kMaskingReader.count(part.parameters, "bins", "provenance/parameters");
  if (bins < 1 || bins > 1000000) malformed("provenance/parameters/bins", "is not a number of bins");
  part.sums = masking_sums_from_json(kMaskingReader.member(report, "sums", ""), std::size_t(bins));
  part.surface = kMaskingReader.text(part.parameters, "surface", "provenance/parameters");
  part.tile_size = kMaskingReader.real(part.parameters, "tile_size", "provenance/parameters");
  try {
    part.geometry = heightfield_geometry_from_string(kMaskingReader.text(part.parameters, "geometry", "provenance/parameters"));
  } catch (const std::invalid_argument& e) {
    malformed("provenance/parameters/geometry", e.what());
  }
  if (report.contains("masking") && report["masking"].contains("seconds") && report["masking"]["seconds"].is_number())
    part.seconds = report["masking"]["seconds"].get<double>();
  return part;
}

namespace {
// Adds `part`'s sums to `sums`, those of the run `parameters` and `provenance` describe (HistogramMergeError
// naming the part `name` otherwise).
void add_part_sums(MaskingSums& sums, const nlohmann::json& parameters, const Provenance& provenance,
                   const MaskingPart& part, const std::string& name) {
  check_same_parameters(parameters, part.parameters, name);
  provenance.check_same_run(part.provenance);
  try {
    sums += part.sums;
  } catch (const std::invalid_argument& e) {
    throw HistogramMergeError(fmt::format("{}: {}", name, e.what()));
  }
}
}  // namespace

MaskingPart merge_masking_parts(const std::vector<MaskingPart>& parts) {
  if (parts.empty()) throw HistogramMergeError("nothing to merge");
  MaskingPart merged = parts.front();
  std::vector<BlockRange> ranges;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const MaskingPart& p = parts[i];
    ranges.push_back(p.provenance.blocks);
    if (i == 0) continue;
    add_part_sums(merged.sums, parts.front().parameters, parts.front().provenance, p, fmt::format("part {}", i + 1));
    merged.seconds += p.seconds;
  }
  merged.provenance.blocks = merge_block_ranges(ranges, merged.provenance.total_blocks, /*require_complete=*/true);
  return merged;
}

void add_masking_part(SurfaceMasking& sum, const MaskingPart& part) {
  add_part_sums(sum.result.sums, sum.parameters, sum.provenance, part, "the part");
  sum.result.rays += part.sums.rays;
}

SurfaceMasking analyse_masking_part(const MaskingPart& part, const MaskingSurface& surface) {
  const std::string digest = surface_digest(surface.field);
  const std::string want = kMaskingReader.text(part.parameters, "surface_digest", "provenance/parameters");
  if (digest != want || surface.field.tile_size() != part.tile_size)
    throw HistogramMergeError(fmt::format("the surface '{}' (digest {}, tile {}) is not the one the parts were traced on "
                                          "(digest {}, tile {})", surface.path, digest, surface.field.tile_size(),
                                          reader::quote_excerpt(want), part.tile_size));
  SurfaceMasking m;
  m.request = request_from_parameters(part.parameters, part.provenance.seed);
  m.parameters = part.parameters;
  m.provenance = part.provenance;
  m.result = masking_result_from_sums(surface.field, surface.analytic, surface.empirical, masking_view(m.request),
                                      masking_options(m.request), part.sums, part.provenance.blocks);
  m.result.seconds = part.seconds;
  return m;
}

MaskingOptions masking_options(const MaskingRequest& r) {
  MaskingOptions o;
  o.samples = r.samples;
  o.seed = r.seed;
  o.blocks = r.blocks;
  o.run = r.run;
  o.normal_bins = o.height_bins = r.bins;
  o.cone_deg = r.cone_deg;
  o.grazing_share = r.grazing_share;
  if (r.theta_l_deg) o.light = direction_from_degrees(*r.theta_l_deg, r.phi_l_deg);
  return o;
}

// ---- the report ----------------------------------------------------------------------------------------------

bool leak_failed(const MaskingResult& r) {
  if (r.leaked > 0) return true;
  return std::abs(r.leak_ratio.value - 1.0) > kLeakSigmas * r.leak_ratio.standard_error;
}

bool masking_is_partial(const SurfaceMasking& m) {
  return m.result.partial || (m.vndf && m.vndf->trace.partial) || (m.request.vndf_rays > 0 && !m.vndf);
}

namespace {
nlohmann::json masking_vndf_json(const MaskingVndf& v) {
  nlohmann::json jv;
  jv["rays"] = v.trace.rays;
  jv["hits"] = v.trace.hits;
  jv["backfacing"] = v.diagnostics.backfacing;
  jv["edge_grazes"] = v.diagnostics.edge_grazes;
  jv["leaked"] = v.diagnostics.leaked;
  jv["rays_per_second"] = v.trace.rays_per_second();
  jv["partial"] = v.trace.partial;
  for (const auto& c : v.comparisons) jv["comparisons"].push_back(to_json(c));
  return jv;
}
}  // namespace

nlohmann::json surface_masking_json(const SurfaceMasking& m, const MaskingSurface& surface) {
  const MaskingRequest& q = m.request;
  nlohmann::json j = masking_part_json(m);  // provenance and sums
  j["surface"] = surface_json(surface.field, surface.path, surface.analytic, surface.reference_source);
  j["geometry"] = to_string(surface.geometry);
  if (surface.scene) {
    j["build_seconds"] = surface.scene->build_seconds();
    j["embree_peak_bytes"] = surface.scene->embree_peak_bytes();
  }
  j["theta"] = q.theta_deg;
  j["phi"] = q.phi_deg;
  if (q.theta_l_deg) j["theta_l"] = *q.theta_l_deg, j["phi_l"] = q.phi_l_deg;
  j["seed"] = q.seed;
  j["threads"] = q.run.threads;
  j["masking"] = to_json(m.result);
  j["leak_test"] = {{"sigmas", kLeakSigmas}, {"failed", leak_failed(m.result)}};
  if (m.vndf) j["vndf"] = masking_vndf_json(*m.vndf);
  j["partial"] = masking_is_partial(m);
  return j;
}

}  // namespace microsim
