#include "measure/merge.h"

#include "measure/vndf.h"
#include "microgeom/exr_io.h"
#include "stats/histogram_io.h"
#include "stats/part_json.h"
#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"
#include "validate/stability_part.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace microsim {
namespace {

// ---- reading parts -------------------------------------------------------------------------------------

void require_exists(const std::string& path) {
  if (!std::filesystem::exists(path)) throw MergeError(fmt::format("part '{}': no such file", path));
}

bool is_json_part(const std::string& path) { return std::filesystem::path(path).extension() == ".json"; }

nlohmann::json read_json_part(const std::string& path) {
  require_exists(path);
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (report.is_discarded()) throw MergeError(fmt::format("part '{}': not a JSON file", path));
  return report;
}

// read(report) for each JSON part; a HistogramMergeError of part i names paths[i].
template <class Read> auto read_json_parts(const std::vector<std::string>& paths, Read&& read) {
  std::vector<decltype(read(nlohmann::json()))> out;
  for (const std::string& path : paths) {
    const nlohmann::json report = read_json_part(path);
    try {
      out.push_back(read(report));
    } catch (const HistogramMergeError& e) {
      throw MergeError(fmt::format("part '{}': {}", path, e.what()));
    }
  }
  return out;
}

// merge(), a HistogramMergeError turned into "cannot merge: ...".
template <class Merge> auto merged(Merge&& merge) {
  try {
    return merge();
  } catch (const HistogramMergeError& e) {
    throw MergeError(fmt::format("cannot merge: {}", e.what()));
  }
}

ScatterFile read_scatter_part(const std::string& path) {
  require_exists(path);
  try {
    const microgeom::ExrImage image = microgeom::read_exr(path);
    if (!is_scatter_image(image))
      throw MergeError(fmt::format("cannot merge: part '{}' is not a scatter file (microsim scatter --shard) but the "
                                   "first part is: parts of one run are of one kind", path));
    ScatterFile f = scatter_from_exr(image, path);
    if (f.kind != ScatterFileKind::histogram)
      throw MergeError(fmt::format("cannot merge: part '{}' is an expectation (microsim scatter --model analytic), "
                                   "not part of a sampled run", path));
    return f;
  } catch (const ScatterIoError& e) {
    throw MergeError(e.what());
  } catch (const std::runtime_error& e) {  // not an EXR file (MergeError is no runtime_error)
    throw MergeError(fmt::format("part '{}': {}", path, e.what()));
  }
}

// ---- one merge per kind --------------------------------------------------------------------------------

MergedRun merge_vndf(const std::vector<std::string>& paths) {
  std::vector<TracedHistogram> parts;
  for (const std::string& path : paths) {
    require_exists(path);
    try {
      parts.push_back(read_histogram_exr(path));
    } catch (const HistogramIoError& e) {
      throw MergeError(e.what());
    }
  }
  MergedVndf m;
  m.histogram = merged([&] { return merge_vndf_parts(parts, m.unbinned); });
  return {PartKind::vndf, parts.size(), std::move(m)};
}

MergedRun merge_scatter(const std::vector<std::string>& paths) {
  std::vector<ScatterHistogram> parts;
  MergedScatter m;
  for (const std::string& path : paths) {
    ScatterFile f = read_scatter_part(path);
    if (parts.empty()) m.notes = f.notes;
    else if (f.notes != m.notes)
      throw MergeError(fmt::format("cannot merge: part '{}' records other notes than part '{}' (another run)", path,
                                   paths.front()));
    parts.push_back(std::move(f.histogram));
  }
  m.histogram = merged([&] { return merge_scatter_parts(parts); });
  return {PartKind::scatter, parts.size(), std::move(m)};
}

MergedRun merge_masking(const std::vector<std::string>& paths) {
  const std::vector<MaskingPart> parts = read_json_parts(paths, read_masking_part);
  return {PartKind::masking, parts.size(), merged([&] { return merge_masking_parts(parts); })};
}

MergedRun merge_validation(const std::vector<std::string>& paths) {
  const std::vector<ValidationPart> parts = read_json_parts(paths, read_validation_part);
  return {PartKind::validate, parts.size(), merged([&] { return merge_validation_parts(parts); })};
}

MergedRun merge_stability(const std::vector<std::string>& paths) {
  const std::vector<StabilityTable> parts = read_json_parts(paths, read_stability_part);
  return {PartKind::stability, parts.size(), merged([&] { return merge_stability_parts(parts); })};
}

// The kinds: the producer of their parts (for JSON parts, the provenance's producer) and their merge.
struct PartKindEntry {
  PartKind kind;
  const char* producer;
  bool json;
  MergedRun (*merge)(const std::vector<std::string>&);
};

constexpr std::array<PartKindEntry, 5> kPartKinds{{
    {PartKind::vndf, "trace vndf", false, merge_vndf},
    {PartKind::scatter, "scatter", false, merge_scatter},
    {PartKind::masking, "trace masking", true, merge_masking},
    {PartKind::validate, "validate", true, merge_validation},
    {PartKind::stability, "stability", true, merge_stability},
}};

const PartKindEntry& entry_of(PartKind kind) {
  for (const PartKindEntry& e : kPartKinds)
    if (e.kind == kind) return e;
  throw std::logic_error("unknown part kind");
}

// The JSON kinds, by name: "trace masking, validate, stability".
std::string json_kinds() {
  std::string names;
  for (const PartKindEntry& e : kPartKinds)
    if (e.json) names += (names.empty() ? "" : ", ") + std::string(e.producer);
  return names;
}

// Every part is of one kind: JSON parts or EXR histograms.
void check_one_kind(const std::vector<std::string>& paths) {
  const auto kind = [](const std::string& p) { return is_json_part(p) ? "a JSON report" : "a trace vndf histogram"; };
  for (const std::string& p : paths)
    if (is_json_part(p) != is_json_part(paths.front()))
      throw MergeError(fmt::format("cannot merge: part '{}' is {} and part '{}' {}: parts of one run are of one kind",
                                   paths.front(), kind(paths.front()), p, kind(p)));
}

PartKind json_kind(const std::vector<std::string>& paths) {
  std::vector<std::string> producers;
  for (const std::string& path : paths) producers.push_back(producer_of(read_json_part(path)));
  const PartKindEntry* found = nullptr;
  for (const PartKindEntry& e : kPartKinds)
    if (e.json && producers.front() == e.producer) found = &e;
  if (!found)
    throw MergeError(fmt::format("part '{}': not a partial result of {} (its provenance names no such producer; VNDF "
                                 "parts are the .exr histograms of trace vndf --shard)", paths.front(), json_kinds()));
  for (std::size_t i = 1; i < producers.size(); ++i)
    if (producers[i] != found->producer)
      throw MergeError(fmt::format("part '{}': not a {} report (its provenance's producer is not \"{}\"; parts of one "
                                   "run are of one kind, and VNDF parts are the .exr histograms of trace vndf --shard)",
                                   paths[i], found->producer, found->producer));
  return found->kind;
}

}  // namespace

const char* part_kind_name(PartKind kind) { return entry_of(kind).producer; }

PartKind merge_kind(const std::vector<std::string>& paths) {
  if (paths.empty()) throw MergeError("cannot merge: no parts");
  check_one_kind(paths);
  if (is_json_part(paths.front())) return json_kind(paths);
  return is_scatter_part(paths.front()) ? PartKind::scatter : PartKind::vndf;
}

MergedRun merge_parts(const std::vector<std::string>& paths) { return merge_parts(merge_kind(paths), paths); }

MergedRun merge_parts(PartKind kind, const std::vector<std::string>& paths) { return entry_of(kind).merge(paths); }

MergedEllipsoid analyse_merged_ellipsoid(MergedVndf merged) {
  MergedEllipsoid e;
  const GGX<double> ggx = histogram_ggx(merged.histogram);
  e.target = std::make_unique<EllipsoidTarget>(ggx.alpha_x(), ggx.alpha_y(), vndf_run_record(merged.histogram).mesh_level);
  const Vec3<double> wi = vndf_view(merged.histogram);
  e.vndf = analyse_ellipsoid_vndf(std::move(merged.histogram), merged.unbinned);
  e.vndf.expected_hit_fraction = ParallelBeam(e.target->ellipsoid(), wi).expected_hit_fraction();
  return e;
}

bool is_scatter_part(const std::string& path) {
  if (is_json_part(path) || !std::filesystem::exists(path)) return false;
  try {
    return is_scatter_image(microgeom::read_exr(path));
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    return false;  // reading it as a histogram names what is wrong with it
  }
}

}  // namespace microsim
