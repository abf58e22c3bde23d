#include "measure/merge.h"

#include "measure/vndf.h"
#include "microgeom/exr_io.h"
#include "stats/part_json.h"
#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"
#include "validate/stability_part.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>

namespace microsim {
namespace {

// ---- reading parts -------------------------------------------------------------------------------------

void require_exists(const std::string& path) {
  if (!std::filesystem::exists(path)) throw MergeError(fmt::format("part '{}': no such file", path));
}

// An OpenEXR file: its magic number, or its name (an empty or truncated .exr file).
bool looks_like_exr(const std::string& path, const std::string& text) {
  return text.rfind(std::string("\x76\x2f\x31\x01", 4), 0) == 0 || std::filesystem::path(path).extension() == ".exr";
}

nlohmann::json read_json_part(const std::string& path) {
  require_exists(path);
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!report.is_discarded()) return report;
  if (looks_like_exr(path, text))
    throw MergeError(fmt::format("part '{}' is an EXR file: parts are JSON now (`trace vndf --shard K/N` and `scatter "
                                 "--shard K/N` write --out PART.json); re-run the shard with this version", path));
  throw MergeError(fmt::format("part '{}': not a JSON file", path));
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

// ---- one merge per kind --------------------------------------------------------------------------------

MergedRun merge_vndf(const std::vector<std::string>& paths) {
  std::vector<TracedHistogram> parts = read_json_parts(paths, read_vndf_part);
  // In block order: the merged histogram keeps the first part's attributes (threads, rate), whatever the
  // order the parts were given in.
  std::stable_sort(parts.begin(), parts.end(), [](const TracedHistogram& a, const TracedHistogram& b) {
    return vndf_provenance(a).blocks.begin < vndf_provenance(b).blocks.begin;
  });
  MergedVndf m;
  m.histogram = merged([&] { return merge_vndf_parts(parts, m.unbinned); });
  return {PartKind::vndf, parts.size(), std::move(m)};
}

// The first note (by key) that two parts record differently, as "KEY 'A' vs 'B'" (a note one lacks: '').
std::string note_difference(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b) {
  const auto value = [](const std::map<std::string, std::string>& notes, const std::string& key) {
    const auto it = notes.find(key);
    return it == notes.end() ? std::string() : it->second;
  };
  std::set<std::string> keys;
  for (const auto* notes : {&a, &b})
    for (const auto& [key, text] : *notes) keys.insert(key);
  for (const std::string& key : keys)
    if (value(a, key) != value(b, key)) return fmt::format("{} '{}' vs '{}'", key, value(a, key), value(b, key));
  return "";
}

MergedRun merge_scatter(const std::vector<std::string>& paths) {
  std::vector<ScatterPart> read = read_json_parts(paths, read_scatter_part);
  std::vector<ScatterHistogram> parts;
  MergedScatter m;
  m.notes = read.front().notes;
  for (std::size_t i = 0; i < read.size(); ++i) {
    if (read[i].notes != m.notes)
      throw MergeError(fmt::format("cannot merge: part '{}' records other notes than part '{}' (another run: {})",
                                   paths[i], paths.front(), note_difference(read[i].notes, m.notes)));
    parts.push_back(std::move(read[i].histogram));
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

MergedRun merge_albedo(const std::vector<std::string>& paths) {
  const std::vector<AlbedoPart> parts = read_json_parts(paths, read_albedo_part);
  return {PartKind::albedo, parts.size(), merged([&] { return merge_albedo_parts(parts); })};
}

// The kinds: the producer their parts' provenance names, and their merge.
struct PartKindEntry {
  PartKind kind;
  const char* producer;
  MergedRun (*merge)(const std::vector<std::string>&);
};

constexpr std::array<PartKindEntry, 6> kPartKinds{{
    {PartKind::vndf, kVndfPartProducer, merge_vndf},
    {PartKind::scatter, kScatterPartProducer, merge_scatter},
    {PartKind::masking, "trace masking", merge_masking},
    {PartKind::validate, "validate", merge_validation},
    {PartKind::stability, "stability", merge_stability},
    {PartKind::albedo, kAlbedoPartProducer, merge_albedo},
}};

const PartKindEntry& entry_of(PartKind kind) {
  for (const PartKindEntry& e : kPartKinds)
    if (e.kind == kind) return e;
  throw std::logic_error("unknown part kind");
}

// The kinds, by name: "trace vndf, scatter, trace masking, validate, stability, albedo".
std::string kind_names() {
  std::string names;
  for (const PartKindEntry& e : kPartKinds) names += (names.empty() ? "" : ", ") + std::string(e.producer);
  return names;
}

}  // namespace

const char* part_kind_name(PartKind kind) { return entry_of(kind).producer; }

PartKind merge_kind(const std::vector<std::string>& paths) {
  if (paths.empty()) throw MergeError("cannot merge: no parts");
  std::vector<std::string> producers;
  for (const std::string& path : paths) producers.push_back(producer_of(read_json_part(path)));
  const PartKindEntry* found = nullptr;
  for (const PartKindEntry& e : kPartKinds)
    if (producers.front() == e.producer) found = &e;
  if (!found)
    throw MergeError(fmt::format("part '{}': not a partial result of {} (its provenance names no such producer)",
                                 paths.front(), kind_names()));
  for (std::size_t i = 1; i < producers.size(); ++i)
    if (producers[i] != found->producer)
      throw MergeError(fmt::format("part '{}': not a {} report (its provenance's producer is not \"{}\"; parts of one "
                                   "run are of one kind)", paths[i], found->producer, found->producer));
  return found->kind;
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
  if (!std::filesystem::exists(path)) return false;
  try {
    return is_scatter_image(microgeom::read_exr(path));
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    return false;  // reading it as a histogram names what is wrong with it
  }
}

}  // namespace microsim
