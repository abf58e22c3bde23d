// microsim merge: joins the partial results of one run (`trace vndf --shard K/N` histograms, EXR;
// `trace masking --surface S --shard K/N` reports, JSON; `scatter --shard K/N` scatter files, EXR; or runs
// cancelled part way) into the whole run.
// The parts must come from the same run (every run attribute or parameter equal, same binnings, same seed)
// and together hold every block exactly once; the merged result, its analysis, JSON and table are those
// of the single run, bit for bit (counts are exact integers, masking sums exact fixed-point sums).
//
// Exit codes: 0 merged, 2 bad usage or input (parts of different runs, blocks missing or repeated: the
// ranges are named; nothing written).
#include "command.h"
#include "surface_input.h"
#include "masking_report.h"
#include "vndf_report.h"
#include "merge_scatter.h"

#include "core/output_paths.h"
#include "core/strict_parse.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct MergeArgs {
  std::vector<std::string> parts;
  std::string out, json, surface;
};

std::vector<TracedHistogram> read_parts(const std::vector<std::string>& paths) {
  std::vector<TracedHistogram> parts;
  for (const std::string& path : paths) {
    if (!std::filesystem::exists(path)) throw UsageError(fmt::format("part '{}': no such file", path));
    try {
      parts.push_back(read_histogram_exr(path));
    } catch (const HistogramIoError& e) {
      throw UsageError(e.what());
    }
  }
  return parts;
}

TracedHistogram merge_or_usage_error(const std::vector<TracedHistogram>& parts, std::vector<std::uint64_t>& unbinned) {
  try {
    return merge_vndf_parts(parts, unbinned);
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
}

int report_merged_ellipsoid(TracedHistogram merged, const std::vector<std::uint64_t>& unbinned, const MergeArgs& a) {
  const GGX<double> ggx = histogram_ggx(merged);
  const auto level = reader::parse_finite_double(merged.attributes["mesh_level"]);
  const EllipsoidTarget target(ggx.alpha_x(), ggx.alpha_y(), level ? int(*level) : -1);
  const Vec3<double> wi = vndf_view(merged);
  EllipsoidVndf m = analyse_ellipsoid_vndf(std::move(merged), unbinned);
  m.expected_hit_fraction = ParallelBeam(target.ellipsoid(), wi).expected_hit_fraction();
  return report_ellipsoid_vndf(m, target, {a.out, a.json});
}

// ---- trace masking parts (JSON) -------------------------------------------------------------------------

bool is_json_part(const std::string& path) { return std::filesystem::path(path).extension() == ".json"; }

// Every part is of one kind: masking reports (.json) or VNDF histograms (.exr).
void check_one_kind(const std::vector<std::string>& paths) {
  for (const std::string& p : paths)
    if (is_json_part(p) != is_json_part(paths.front()))
      throw UsageError(fmt::format("cannot merge: part '{}' is {} and part '{}' {}: parts of one run are of one kind",
                                   paths.front(), is_json_part(paths.front()) ? "a trace masking report (.json)" : "a trace vndf histogram",
                                   p, is_json_part(p) ? "a trace masking report (.json)" : "a trace vndf histogram"));
}

MaskingPart read_masking_part_file(const std::string& path) {
  if (!std::filesystem::exists(path)) throw UsageError(fmt::format("part '{}': no such file", path));
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (report.is_discarded()) throw UsageError(fmt::format("part '{}': not a JSON file", path));
  if (!is_masking_part(report))
    throw UsageError(fmt::format("part '{}': not a trace masking report (its provenance's producer is not \"trace "
                                 "masking\"; VNDF parts are the .exr histograms of trace vndf --shard)", path));
  try {
    return read_masking_part(report);
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("part '{}': {}", path, e.what()));
  }
}

int merge_masking(const MergeArgs& a) {
  if (!a.out.empty())
    throw UsageError(fmt::format("--out '{}': trace masking parts merge into a JSON report (--json MERGED.json)", a.out));
  check_output("--json", a.json);
  std::vector<MaskingPart> parts;
  for (const std::string& path : a.parts) parts.push_back(read_masking_part_file(path));
  MaskingPart merged;
  try {
    merged = merge_masking_parts(parts);
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
  fmt::print(stderr, "merge: {} trace masking parts, {} samples, blocks {}\n", parts.size(), merged.sums.samples,
             merged.provenance.blocks.to_string());
  const std::string path = a.surface.empty() ? merged.surface : a.surface;
  const microgeom::Heightfield field = load_surface(path, merged.tile_size);
  const MaskingSurface surface(field, path, merged.geometry, /*trace=*/false);
  try {
    return report_surface_masking(analyse_masking_part(merged, surface), surface, {a.json});
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
}

// ---- the command -----------------------------------------------------------------------------------------

int run_merge(const MergeArgs& a) {
  std::vector<PathOption> inputs;
  for (const std::string& p : a.parts) inputs.push_back({"part", p});
  inputs.push_back({"--surface", a.surface});
  check_distinct_outputs(inputs, {{"--out", a.out}, {"--json", a.json}});
  check_one_kind(a.parts);
  if (is_json_part(a.parts.front())) return merge_masking(a);
  if (is_scatter_part(a.parts.front())) return merge_scatter(a.parts, a.out, a.json, a.surface);
  if (a.out.empty()) throw UsageError("--out MERGED.exr is required to merge trace vndf histograms");
  if (std::filesystem::path(a.out).extension() != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  check_output("--out", a.out);
  check_output("--json", a.json);
  const std::vector<TracedHistogram> parts = read_parts(a.parts);
  std::vector<std::uint64_t> unbinned;
  TracedHistogram merged = merge_or_usage_error(parts, unbinned);
  fmt::print(stderr, "merge: {} parts, {} rays, blocks {}\n", parts.size(), merged.rays, merged.attributes["blocks"]);
  const std::string surface = merged.attributes["surface"];
  if (surface == "ellipsoid") return report_merged_ellipsoid(std::move(merged), unbinned, a);
  const microgeom::Heightfield field = load_surface(a.surface.empty() ? surface : a.surface, std::nullopt);
  const HeightfieldVndf m = analyse_heightfield_vndf(std::move(merged), unbinned, field);
  return report_heightfield_vndf(m, field, {a.out, a.json});
}

CommandRegistration reg{"merge", [](CLI::App& app) {
  auto args = std::make_shared<MergeArgs>();
  auto* sub = app.add_subcommand(
      "merge",
      "Join the partial results of one run (`microsim trace vndf --shard K/N` histograms, `microsim trace masking "
      "--surface S --shard K/N` JSON reports, `microsim scatter --shard K/N` scatter files, or a run interrupted part "
      "way) into the whole run: the same histogram "
      "EXR or JSON report, and the same table, as the single run, bit for bit. The parts must be of one run and "
      "hold every block exactly once (missing or repeated block ranges are named). Exit 0 merged (trace masking: "
      "1 if the merged leak test failed), 2 bad input (nothing written).");
  sub->add_option("parts", args->parts, "partial results of one run, in any order: histograms (EXR) or masking reports (JSON)")
      ->required();
  sub->add_option("--out", args->out, "trace vndf, scatter: the merged histogram EXR to write (required)");
  sub->add_option("--json", args->json, "write the JSON report (trace vndf: also; trace masking: the merged report)");
  sub->add_option("--surface", args->surface,
                  "heightfield runs: the heightmap the parts were traced on (default: the path they record)");
  on_selected(sub, [args] { return run_merge(*args); });
}};

}  // namespace
}  // namespace microsim::app
