#include "measure/vndf.h"

#include "core/strict_parse.h"
#include "stats/part_json.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace microsim {

namespace {

std::string g17(double x) { return fmt::format("{:.17g}", x); }

std::vector<DirectionBinning> vndf_binnings(const GGX<double>& ggx, const Vec3<double>& wi, int rows) {
  return {DirectionBinning::sphere(rows), DirectionBinning::lobe(ggx, wi, SampleDomain::microfacet_normal, rows)};
}

TraceOptions trace_options(const VndfRequest& r) {
  TraceOptions t;
  t.rays = r.rays;
  t.seed = r.seed;
  t.blocks = r.blocks;
  t.run = r.run;
  return t;
}

std::string join_counts(const std::vector<std::uint64_t>& v) {
  std::string s;
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (k) s += ',';
    s += std::to_string(v[k]);
  }
  return s;
}

// The histogram of a trace, with the attributes every trace vndf histogram carries.
TracedHistogram traced_histogram(std::vector<DirectionBinning> binnings, const TraceResult& r, const VndfRequest& req,
                                 const Vec3<double>& wi) {
  TracedHistogram h;
  h.binnings = std::move(binnings);
  h.counts = r.counts;
  h.rays = r.rays;
  h.hits = r.hits;
  h.partial = r.partial;
  h.attributes["theta"] = g17(req.theta_deg);
  h.attributes["phi"] = g17(req.phi_deg);
  h.attributes["wi"] = g17(wi.x()) + "," + g17(wi.y()) + "," + g17(wi.z());
  h.attributes["seed"] = std::to_string(req.seed);
  h.attributes["rays_requested"] = std::to_string(req.rays);
  h.attributes["threads"] = std::to_string(req.run.threads);
  h.attributes["rays_per_second"] = g17(r.rays_per_second());
  h.attributes["blocks"] = fmt::format("{},{}", r.blocks.begin, r.blocks.end);
  h.attributes["total_blocks"] = std::to_string(r.total_blocks);
  h.attributes["block_size"] = std::to_string(kRaysPerBlock);
  h.attributes["unbinned"] = join_counts(r.unbinned);
  return h;
}

const std::string& attribute(const TracedHistogram& h, const std::string& key) {
  const auto it = h.attributes.find(key);
  if (it == h.attributes.end())
    throw HistogramMergeError(fmt::format("the histogram has no attribute '{}' (not from `trace vndf`?)", key));
  return it->second;
}

std::uint64_t count_attribute(const TracedHistogram& h, const std::string& key) {
  const std::optional<std::uint64_t> v = reader::parse_uint64(attribute(h, key));
  if (!v) throw HistogramMergeError(fmt::format("attribute {} = {} is not a count", key, reader::quote_excerpt(attribute(h, key))));
  return *v;
}

std::vector<std::uint64_t> count_list_attribute(const TracedHistogram& h, const std::string& key) {
  std::vector<std::uint64_t> values;
  for (const std::string_view item : reader::split_commas(attribute(h, key))) {
    const std::optional<std::uint64_t> v = reader::parse_uint64(item);
    if (!v) throw HistogramMergeError(fmt::format("attribute {} = {} is not a list of counts", key, reader::quote_excerpt(attribute(h, key))));
    values.push_back(*v);
  }
  return values;
}

// Attributes that differ between the parts of one run.
bool is_per_part(const std::string& key) {
  static const std::set<std::string> keys = {"blocks",   "unbinned",    "threads", "rays_per_second", "shard",
                                             "backfacing", "edge_grazes", "leaked",  "unresolved"};
  return keys.count(key) > 0;
}

void check_same_run(const TracedHistogram& a, const TracedHistogram& b, const std::string& name) {
  for (const auto& [key, value] : a.attributes) {
    if (is_per_part(key)) continue;
    const auto it = b.attributes.find(key);
    if (it == b.attributes.end() || it->second != value)
      throw HistogramMergeError(fmt::format("{} is not part of the same run: attribute {} is {} there, {} in the first part",
                                            name, key, it == b.attributes.end() ? "missing" : reader::quote_excerpt(it->second),
                                            reader::quote_excerpt(value)));
  }
  if (a.binnings.size() != b.binnings.size())
    throw HistogramMergeError(fmt::format("{} is not part of the same run: different binnings", name));
  for (std::size_t k = 0; k < a.binnings.size(); ++k)
    if (a.binnings[k].describe() != b.binnings[k].describe())
      throw HistogramMergeError(fmt::format("{} is not part of the same run: binning {} differs", name, a.binnings[k].name()));
}

double real_attribute(const TracedHistogram& h, const std::string& key) {
  const std::optional<double> v = reader::parse_finite_double(attribute(h, key));
  if (!v) throw HistogramMergeError(fmt::format("attribute {} = {} is not a number", key, reader::quote_excerpt(attribute(h, key))));
  return *v;
}

// The attribute "blocks" = "B,E": a range within the run's blocks.
BlockRange blocks_attribute(const TracedHistogram& h, std::uint64_t total_blocks) {
  const std::vector<std::uint64_t> blocks = count_list_attribute(h, "blocks");
  if (blocks.size() != 2 || blocks[0] > blocks[1] || blocks[1] > total_blocks)
    throw HistogramMergeError(fmt::format("attribute blocks = {} is not a range B,E within the run's {} blocks",
                                          reader::quote_excerpt(attribute(h, "blocks")), total_blocks));
  return {blocks[0], blocks[1]};
}

// The trace a histogram holds (no timing): what a merged run reports.
TraceResult trace_of(const TracedHistogram& h, const std::vector<std::uint64_t>& unbinned) {
  TraceResult t;
  t.rays = h.rays;
  t.hits = h.hits;
  t.counts = h.counts;
  t.unbinned = unbinned;
  t.partial = h.partial;
  return t;
}

}  // namespace

Vec3<double> vndf_view(const TracedHistogram& h) {
  return direction_from_degrees(real_attribute(h, "theta"), real_attribute(h, "phi"));
}

VndfRunRecord vndf_run_record(const TracedHistogram& h) {
  VndfRunRecord r;
  r.theta_deg = real_attribute(h, "theta");
  r.phi_deg = real_attribute(h, "phi");
  r.rays_requested = count_attribute(h, "rays_requested");
  r.seed = count_attribute(h, "seed");
  r.threads = count_attribute(h, "threads");
  r.total_blocks = count_attribute(h, "total_blocks");
  r.blocks = blocks_attribute(h, r.total_blocks);
  r.surface = attribute(h, "surface");
  r.target = attribute(h, "target");
  const std::optional<double> level = reader::parse_finite_double(attribute(h, "mesh_level"));
  if (!level || *level != std::floor(*level) || *level < -1 || *level > 64)
    throw HistogramMergeError(fmt::format("attribute mesh_level = {} is not a tessellation level",
                                          reader::quote_excerpt(attribute(h, "mesh_level"))));
  r.mesh_level = int(*level);
  return r;
}

Provenance vndf_provenance(const TracedHistogram& h) {
  Provenance p;
  p.producer = "trace vndf";
  p.seed = count_attribute(h, "seed");
  p.total_blocks = count_attribute(h, "total_blocks");
  p.blocks = blocks_attribute(h, p.total_blocks);
  return p;
}

EllipsoidVndf analyse_ellipsoid_vndf(TracedHistogram histogram, const std::vector<std::uint64_t>& unbinned) {
  EllipsoidVndf m;
  const GGX<double> ggx = histogram_ggx(histogram);
  const Vec3<double> wi = vndf_view(histogram);
  m.analysis = analyse_against_vndf(histogram, ggx, wi, unbinned);
  m.trace = trace_of(histogram, unbinned);
  m.histogram = std::move(histogram);
  return m;
}

EllipsoidVndf measure_ellipsoid_vndf(const EllipsoidTarget& target, const VndfRequest& req) {
  const GGX<double> ggx(target.ellipsoid().ax, target.ellipsoid().ay);
  const Vec3<double> wi = direction_from_degrees(req.theta_deg, req.phi_deg);
  std::vector<DirectionBinning> binnings = vndf_binnings(ggx, wi, req.rows);
  const TraceResult r = trace_vndf(target, wi, binnings, trace_options(req));
  TracedHistogram h = traced_histogram(std::move(binnings), r, req, wi);
  record_ellipsoid_target(h, target);
  EllipsoidVndf m = analyse_ellipsoid_vndf(std::move(h), r.unbinned);
  m.trace = r;
  m.expected_hit_fraction = ParallelBeam(target.ellipsoid(), wi).expected_hit_fraction();
  return m;
}

HeightfieldVndf analyse_heightfield_vndf(TracedHistogram histogram, const std::vector<std::uint64_t>& unbinned,
                                         const microgeom::Heightfield& field) {
  HeightfieldVndf m;
  m.diagnostics = heightfield_diagnostics(histogram);
  const AnalyticSmith analytic = analytic_reference(field, &m.reference_source);
  const EmpiricalSmith empirical(field);
  const Vec3<double> wi = vndf_view(histogram);
  histogram.probability.clear();
  for (std::size_t k = 0; k < histogram.binnings.size(); ++k) {
    m.comparisons.push_back(compare_vndf(histogram.counts[k], k < unbinned.size() ? unbinned[k] : 0,
                                         histogram.binnings[k], wi, analytic, empirical));
    histogram.probability.push_back(m.comparisons.back().p_analytic);
  }
  m.trace = trace_of(histogram, unbinned);
  m.histogram = std::move(histogram);
  return m;
}

HeightfieldVndf trace_heightfield_vndf(const HeightfieldScene& scene, const microgeom::Heightfield& field,
                                       const std::string& surface, const VndfRequest& req) {
  const AnalyticSmith analytic = analytic_reference(field);
  const Vec3<double> wi = direction_from_degrees(req.theta_deg, req.phi_deg);
  std::vector<DirectionBinning> binnings =
      vndf_binnings(GGX<double>(analytic.alpha_x(), analytic.alpha_y()), wi, req.rows);
  HeightfieldVndf m;
  m.trace = trace_vndf_heightfield(scene, wi, binnings, trace_options(req), &m.diagnostics);
  TracedHistogram& h = m.histogram = traced_histogram(std::move(binnings), m.trace, req, wi);
  h.attributes["surface"] = surface;
  h.attributes["target"] = fmt::format("heightfield {} x {} tile {}", field.resolution(), field.resolution(), g17(field.tile_size()));
  h.attributes["mesh_level"] = "-1";
  h.attributes["alpha"] = g17(analytic.alpha_x()) + "," + g17(analytic.alpha_y());
  h.attributes["reference_ndf"] = to_string(analytic.ndf());
  h.attributes["backfacing"] = std::to_string(m.diagnostics.backfacing);
  h.attributes["edge_grazes"] = std::to_string(m.diagnostics.edge_grazes);
  h.attributes["leaked"] = std::to_string(m.diagnostics.leaked);
  h.attributes["unresolved"] = std::to_string(m.diagnostics.unresolved);
  return m;
}

HeightfieldVndf measure_heightfield_vndf(const microgeom::Heightfield& field, const std::string& surface,
                                         const VndfRequest& req) {
  const HeightfieldScene scene(field, req.geometry);
  HeightfieldVndf traced = trace_heightfield_vndf(scene, field, surface, req);
  HeightfieldVndf m = analyse_heightfield_vndf(std::move(traced.histogram), traced.trace.unbinned, field);
  m.trace = std::move(traced.trace);
  m.diagnostics = traced.diagnostics;
  return m;
}

namespace {
// Adds a part's unbinned rays (attribute "unbinned", per binning) to `unbinned`.
void add_unbinned(std::vector<std::uint64_t>& unbinned, const TracedHistogram& part) {
  const std::vector<std::uint64_t> u = count_list_attribute(part, "unbinned");
  if (u.size() != unbinned.size())
    throw HistogramMergeError(fmt::format("attribute unbinned has {} values where the sum has {}", u.size(), unbinned.size()));
  for (std::size_t k = 0; k < u.size(); ++k) unbinned[k] += u[k];
}
}  // namespace

TracedHistogram merge_vndf_parts(const std::vector<TracedHistogram>& parts, std::vector<std::uint64_t>& unbinned) {
  if (parts.empty()) throw HistogramMergeError("nothing to merge");
  const Provenance first = vndf_provenance(parts.front());
  std::vector<BlockRange> ranges;
  TracedHistogram merged = parts.front();
  unbinned.assign(merged.binnings.size(), 0);
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const TracedHistogram& p = parts[i];
    const std::string name = fmt::format("part {}", i + 1);
    check_same_run(parts.front(), p, name);
    first.check_same_run(vndf_provenance(p));
    ranges.push_back(vndf_provenance(p).blocks);
    try {
      if (i == 0) add_unbinned(unbinned, p);  // its other sums are merged's own
      else add_vndf_part(merged, unbinned, p);
    } catch (const HistogramMergeError& e) {
      throw HistogramMergeError(fmt::format("{}: {}", name, e.what()));
    }
  }
  const BlockRange all = merge_block_ranges(ranges, first.total_blocks, /*require_complete=*/true);
  merged.partial = false;
  merged.attributes["blocks"] = fmt::format("{},{}", all.begin, all.end);
  merged.attributes["unbinned"] = join_counts(unbinned);
  merged.attributes.erase("shard");
  return merged;
}

void add_vndf_part(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const TracedHistogram& part) {
  add_unbinned(unbinned, part);
  if (part.counts.size() != sum.counts.size()) throw HistogramMergeError("the parts' binnings differ");
  for (std::size_t k = 0; k < sum.counts.size(); ++k)
    if (part.counts[k].size() != sum.counts[k].size()) throw HistogramMergeError("the parts' binnings differ");
  add_heightfield_diagnostics(sum, part);
  sum.rays += part.rays;
  sum.hits += part.hits;
  for (std::size_t k = 0; k < sum.counts.size(); ++k)
    for (std::size_t b = 0; b < sum.counts[k].size(); ++b) sum.counts[k][b] += part.counts[k][b];
}

// ---- the part as JSON -------------------------------------------------------------------------------------------

namespace {
// The attributes the part's provenance records apart (its seed and blocks) and so leaves out of the others.
bool is_provenance_attribute(const std::string& key) { return key == "seed" || key == "blocks" || key == "total_blocks"; }
}  // namespace

nlohmann::json vndf_part_json(const TracedHistogram& h) {
  nlohmann::json parameters = nlohmann::json::object(), own = nlohmann::json::object();
  for (const auto& [key, value] : h.attributes)
    if (!is_provenance_attribute(key)) (is_per_part(key) ? own : parameters)[key] = value;
  nlohmann::json binnings = nlohmann::json::array();
  for (const DirectionBinning& b : h.binnings) binnings.push_back(b.describe());
  Provenance p = vndf_provenance(h);
  p.producer = kVndfPartProducer;
  return {{"provenance", provenance_json(p, parameters)}, {"rays", h.rays}, {"hits", h.hits}, {"partial", h.partial},
          {"binnings", binnings}, {"counts", h.counts}, {"attributes", own}};
}

namespace {

// A binning of a part: sphere or lobe (a lobe's roughness positive, its view finite), rebuilt.
DirectionBinning read_part_binning(const PartReader& r, const nlohmann::json& d, const std::string& where) {
  const std::string kind = d.is_object() && d.contains("kind") && d["kind"].is_string() ? d["kind"].get<std::string>() : "";
  if (kind != "sphere" && kind != "lobe") r.malformed(where, "is not the description of a sphere or lobe binning");
  const auto finite = [&](const char* key, std::size_t n) {
    if (!d.contains(key) || !d[key].is_array() || d[key].size() != n) return false;
    for (const nlohmann::json& v : d[key])
      if (!v.is_number() || !std::isfinite(v.get<double>())) return false;
    return true;
  };
  if (kind == "lobe" && (!finite("alpha", 2) || !(d["alpha"][0].get<double>() > 0 && d["alpha"][1].get<double>() > 0) ||
                         !finite("wi", 3) || !d.contains("domain") || !d["domain"].is_string()))
    r.malformed(where, "needs alpha (2 positive numbers), wi (3 finite numbers) and domain");
  try {
    return DirectionBinning::from_description(d);
  } catch (const std::invalid_argument& e) {
    r.malformed(where, std::string(e.what()).substr(0, 200));
  }
}

// Member `key` of a part: an object of string values, added to `attributes`.
void read_attributes(const PartReader& r, const nlohmann::json& j, const std::string& where,
                     std::map<std::string, std::string>& attributes) {
  if (!j.is_object()) r.malformed(where, "is not an object");
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!it.value().is_string() || is_provenance_attribute(it.key()))
      r.malformed(where + "/" + it.key(), "is not an attribute (a string, not seed or blocks)");
    attributes[it.key()] = it.value().get<std::string>();
  }
}

// The binnings and their counts: one of each kind at most, all of the same rows, counts adding up to at
// most the hits.
void read_part_counts(const PartReader& r, const nlohmann::json& report, TracedHistogram& h) {
  const nlohmann::json& binnings = r.member(report, "binnings", "");
  if (!binnings.is_array() || binnings.empty() || binnings.size() > 2) r.malformed("binnings", "is not an array of 1 or 2");
  const nlohmann::json& counts = r.array(report, "counts", binnings.size(), "");
  for (std::size_t k = 0; k < binnings.size(); ++k) {
    DirectionBinning b = read_part_binning(r, binnings[k], fmt::format("binnings/{}", k));
    if (h.find(b.kind()) >= 0 || (k > 0 && b.rows() != h.binnings.front().rows()))
      r.malformed("binnings", "holds a binning twice, or binnings of different rows");
    const nlohmann::json& bins = counts[k];
    const std::string where = fmt::format("counts/{}", k);
    if (!bins.is_array() || bins.size() != std::size_t(b.size()))
      r.malformed(where, fmt::format("is not an array of {} counts", b.size()));
    std::vector<std::uint64_t> c;
    std::uint64_t total = 0;
    for (const nlohmann::json& v : bins) {
      if (!v.is_number_unsigned()) r.malformed(where, "holds a value that is not a count");
      c.push_back(v.get<std::uint64_t>());
      if (c.back() > h.hits - total) r.malformed(where, "adds up to more than the hits");
      total += c.back();
    }
    h.binnings.push_back(std::move(b));
    h.counts.push_back(c);
  }
}

}  // namespace

TracedHistogram read_vndf_part(const nlohmann::json& report) {
  const PartReader r(kVndfPartProducer);
  nlohmann::json parameters;
  const Provenance p = r.provenance(report, parameters);
  TracedHistogram h;
  h.rays = r.count(report, "rays", "");
  h.hits = r.count(report, "hits", "");
  if (h.hits > h.rays) r.malformed("hits", "is more than rays");
  h.partial = r.flag(report, "partial", "");
  read_part_counts(r, report, h);
  read_attributes(r, parameters, "provenance/parameters", h.attributes);
  read_attributes(r, r.member(report, "attributes", ""), "attributes", h.attributes);
  h.attributes["seed"] = std::to_string(p.seed);
  h.attributes["total_blocks"] = std::to_string(p.total_blocks);
  h.attributes["blocks"] = fmt::format("{},{}", p.blocks.begin, p.blocks.end);
  return h;
}

HeightfieldVndfDiagnostics heightfield_diagnostics(const TracedHistogram& h) {
  if (!h.attributes.count("backfacing")) return {};
  return {count_attribute(h, "backfacing"), count_attribute(h, "edge_grazes"), count_attribute(h, "leaked"),
          count_attribute(h, "unresolved")};
}

void add_heightfield_diagnostics(TracedHistogram& sum, const TracedHistogram& part) {
  for (const char* key : {"backfacing", "edge_grazes", "leaked", "unresolved"})
    if (sum.attributes.count(key)) sum.attributes[key] = std::to_string(count_attribute(sum, key) + count_attribute(part, key));
}

nlohmann::json vndf_run_json(const TracedHistogram& h, const TraceResult& r, const std::string& out) {
  const Vec3<double> wi = vndf_view(h);
  const GGX<double> ggx = histogram_ggx(h);
  const VndfRunRecord run = vndf_run_record(h);
  nlohmann::json j;
  j["alpha"] = {ggx.alpha_x(), ggx.alpha_y()};
  j["theta"] = run.theta_deg;
  j["phi"] = run.phi_deg;
  j["wi"] = {wi.x(), wi.y(), wi.z()};
  j["rays_requested"] = run.rays_requested;
  j["rays"] = r.rays;
  j["hits"] = r.hits;
  j["hit_fraction"] = r.rays ? double(r.hits) / double(r.rays) : 0.0;
  j["seconds"] = r.seconds;
  j["rays_per_second"] = r.rays_per_second();
  j["seed"] = run.seed;
  j["threads"] = run.threads;
  j["rows"] = h.binnings.front().rows();
  j["partial"] = r.partial;
  j["output"] = out;
  j["blocks"] = fmt::format("{},{}", run.blocks.begin, run.blocks.end);
  j["total_blocks"] = run.total_blocks;
  return j;
}

nlohmann::json surface_json(const microgeom::Heightfield& field, const std::string& path, const AnalyticSmith& analytic,
                            const std::string& source) {
  nlohmann::json j;
  j["path"] = path;
  j["resolution"] = field.resolution();
  j["tile_size"] = field.tile_size();
  j["min_height"] = field.min_height();
  j["max_height"] = field.max_height();
  j["metadata"] = field.metadata;
  j["analytic_reference"] = {{"ndf", to_string(analytic.ndf())},
                             {"alpha", {analytic.alpha_x(), analytic.alpha_y()}},
                             {"source", source}};
  return j;
}

nlohmann::json heightfield_vndf_json(const HeightfieldVndf& m, const microgeom::Heightfield& field, const std::string& out) {
  const TracedHistogram& h = m.histogram;
  const VndfRunRecord run = vndf_run_record(h);
  const VndfComparison& lobe = m.comparisons.back();
  nlohmann::json j = vndf_run_json(h, m.trace, out);
  j["surface"] = surface_json(field, run.surface, analytic_reference(field), m.reference_source);
  j["target"] = run.target;
  j["expected_hit_fraction"] = 1.0;  // every downward ray hits a heightfield
  j["backfacing_hits"] = m.diagnostics.backfacing;
  j["edge_grazes"] = m.diagnostics.edge_grazes;
  j["leaked_rays"] = m.diagnostics.leaked;
  j["total_variation"] = lobe.tv_analytic;
  j["total_variation_own_ndf"] = lobe.tv_empirical;
  j["noise_floor_tv"] = lobe.tv_noise;
  j["p_value"] = lobe.p_value_analytic;
  j["p_value_own_ndf"] = lobe.p_value_empirical;
  for (const auto& c : m.comparisons) j["comparisons"].push_back(to_json(c));
  return j;
}

nlohmann::json ellipsoid_vndf_json(const EllipsoidVndf& m, const EllipsoidTarget& target, const std::string& out) {
  nlohmann::json j = vndf_run_json(m.histogram, m.trace, out);
  j["surface"] = "ellipsoid";
  j["target"] = target.describe();
  j["mesh_level"] = target.mesh_level();
  j["triangles"] = target.triangle_count();
  j["expected_hit_fraction"] = m.expected_hit_fraction;
  j["cpu_seconds"] = m.trace.cpu_seconds;
  j["cpu_ns_per_ray"] = m.trace.cpu_ns_per_ray();
  const auto& lobe_fit = m.analysis.fits.back().binning == "lobe" ? m.analysis.fits.back() : m.analysis.fits.front();
  j["total_variation"] = lobe_fit.total_variation;  // lobe bins resolve the lobe at every alpha
  j["noise_floor_tv"] = lobe_fit.noise_floor_tv;
  j["p_value"] = m.analysis.p_value;
  j["analysis"] = to_json(m.analysis);
  return j;
}

double vndf_noise_floor(const EllipsoidVndf& m) {
  double worst = 0;
  for (const TraceFit& f : m.analysis.fits) worst = std::max(worst, f.noise_floor_tv);
  return worst;
}

double vndf_total_variation(const EllipsoidVndf& m) {
  double worst = 0;
  for (const TraceFit& f : m.analysis.fits) worst = std::max(worst, f.total_variation);
  return worst;
}

double heightfield_noise_floor(const HeightfieldVndf& m) {
  double worst = 0;
  for (const VndfComparison& c : m.comparisons) worst = std::max(worst, c.tv_noise);
  return worst;
}

double heightfield_total_variation(const HeightfieldVndf& m) {
  double worst = 0;
  for (const VndfComparison& c : m.comparisons) worst = std::max(worst, c.tv_analytic);
  return worst;
}

}  // namespace microsim
