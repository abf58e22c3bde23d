// microsim merge: joins the partial results of one run (`trace vndf --shard K/N` histograms, EXR;
// `trace masking --surface S --shard K/N`, `validate ... --shard K/N` and `stability --shard K/N` reports,
// JSON, told apart by their provenance's producer; `scatter --shard K/N` scatter files, EXR; or runs cancelled
// part way) into the whole run.
// The parts must come from the same run (every run attribute or parameter equal, same binnings, same seed)
// and together hold every block exactly once; the merged result, its analysis, JSON and table are those
// of the single run, bit for bit (counts are exact integers, masking sums exact fixed-point sums).
//
// Exit codes: 0 merged (1: the merged run rejects, as the single run would), 2 bad usage or input (parts
// of different runs, blocks missing or repeated: the ranges are named; nothing written).
#include "command.h"
#include "merge_parts.h"
#include "surface_input.h"
#include "masking_report.h"
#include "stability_report.h"
#include "validate_report.h"
#include "vndf_report.h"
#include "merge_scatter.h"

#include "core/output_paths.h"
#include "stats/part_json.h"

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

int report_merged_ellipsoid(TracedHistogram merged, const std::vector<std::uint64_t>& unbinned, const MergeArgs& a) {
  const GGX<double> ggx = histogram_ggx(merged);
  const EllipsoidTarget target(ggx.alpha_x(), ggx.alpha_y(), vndf_run_record(merged).mesh_level);
  const Vec3<double> wi = vndf_view(merged);
  EllipsoidVndf m = analyse_ellipsoid_vndf(std::move(merged), unbinned);
  m.expected_hit_fraction = ParallelBeam(target.ellipsoid(), wi).expected_hit_fraction();
  return report_ellipsoid_vndf(m, target, {a.out, a.json});
}

// ---- trace masking parts (JSON) -------------------------------------------------------------------------

bool is_json_part(const std::string& path) { return std::filesystem::path(path).extension() == ".json"; }

// Every part is of one kind: JSON reports (trace masking, validate, stability) or VNDF histograms (.exr).
void check_one_kind(const std::vector<std::string>& paths) {
  for (const std::string& p : paths)
    if (is_json_part(p) != is_json_part(paths.front()))
      throw UsageError(fmt::format("cannot merge: part '{}' is {} and part '{}' {}: parts of one run are of one kind",
                                   paths.front(), is_json_part(paths.front()) ? "a JSON report" : "a trace vndf histogram",
                                   p, is_json_part(p) ? "a JSON report" : "a trace vndf histogram"));
}

nlohmann::json read_json_part(const std::string& path) {
  if (!std::filesystem::exists(path)) throw UsageError(fmt::format("part '{}': no such file", path));
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (report.is_discarded()) throw UsageError(fmt::format("part '{}': not a JSON file", path));
  return report;
}

int merge_masking(const MergeArgs& a, const std::vector<nlohmann::json>& reports) {
  if (!a.out.empty())
    throw UsageError(fmt::format("--out '{}': trace masking parts merge into a JSON report (--json MERGED.json)", a.out));
  check_output("--json", a.json);
  const std::vector<MaskingPart> parts = read_json_parts(reports, a.parts, read_masking_part);
  const MaskingPart merged = merged_or_usage_error([&] { return merge_masking_parts(parts); });
  fmt::print(stderr, "merge: {} trace masking parts, {} samples, blocks {}\n", parts.size(), merged.sums.samples,
             merged.provenance.blocks.to_string());
  const std::string path = a.surface.empty() ? merged.surface : a.surface;
  const microgeom::Heightfield field = load_surface(path, merged.tile_size);
  const MaskingSurface surface(field, path, merged.geometry, /*trace=*/false);
  return report_surface_masking(merged_or_usage_error([&] { return analyse_masking_part(merged, surface); }), surface,
                                {a.json});
}

// ---- JSON parts: of trace masking, validate or stability, by their provenance's producer ------------------

// The producers whose JSON parts merge here.
std::string json_kinds() { return "trace masking, validate, stability"; }

int merge_json_parts(const MergeArgs& a) {
  std::vector<nlohmann::json> reports;
  for (const std::string& path : a.parts) reports.push_back(read_json_part(path));
  const std::string producer = producer_of(reports.front());
  if (producer != "trace masking" && producer != "validate" && producer != "stability")
    throw UsageError(fmt::format("part '{}': not a partial result of {} (its provenance names no such producer; VNDF "
                                 "parts are the .exr histograms of trace vndf --shard)", a.parts.front(), json_kinds()));
  for (std::size_t i = 1; i < reports.size(); ++i)
    if (producer_of(reports[i]) != producer)
      throw UsageError(fmt::format("part '{}': not a {} report (its provenance's producer is not \"{}\"; parts of one "
                                   "run are of one kind, and VNDF parts are the .exr histograms of trace vndf --shard)",
                                   a.parts[i], producer, producer));
  if (producer == "trace masking") return merge_masking(a, reports);
  if (!a.out.empty())
    throw UsageError(fmt::format("--out '{}': {} parts merge into a JSON report (--json MERGED.json)", a.out, producer));
  if (!a.surface.empty()) throw UsageError(fmt::format("--surface applies to heightfield parts, not to {} parts", producer));
  check_output("--json", a.json);
  if (producer == "validate") return merge_validation(reports, a.parts, a.json);
  return merge_stability(reports, a.parts, a.json);
}

// ---- the command -----------------------------------------------------------------------------------------

int run_merge(const MergeArgs& a) {
  std::vector<PathOption> inputs;
  for (const std::string& p : a.parts) inputs.push_back({"part", p});
  inputs.push_back({"--surface", a.surface});
  check_distinct_outputs(inputs, {{"--out", a.out}, {"--json", a.json}});
  check_one_kind(a.parts);
  if (is_json_part(a.parts.front())) return merge_json_parts(a);
  if (is_scatter_part(a.parts.front())) return merge_scatter(a.parts, a.out, a.json, a.surface);
  if (a.out.empty()) throw UsageError("--out MERGED.exr is required to merge trace vndf histograms");
  if (std::filesystem::path(a.out).extension() != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  check_output("--out", a.out);
  check_output("--json", a.json);
  const std::vector<TracedHistogram> parts = read_parts(a.parts);
  std::vector<std::uint64_t> unbinned;
  TracedHistogram merged = merged_or_usage_error([&] { return merge_vndf_parts(parts, unbinned); });
  fmt::print(stderr, "merge: {} parts, {} rays, blocks {}\n", parts.size(), merged.rays, merged.attributes["blocks"]);
  const std::string surface = merged.attributes["surface"];
  if (surface == "ellipsoid") return report_merged_ellipsoid(std::move(merged), unbinned, a);
  const microgeom::Heightfield field = load_surface(a.surface.empty() ? surface : a.surface, std::nullopt);
  const HeightfieldVndf m = analyse_heightfield_vndf(std::move(merged), unbinned, field);
  return report_heightfield_vndf(m, field, {a.out, a.json});
}

CommandRegistration merge_registration{"merge", [](CLI::App& app) {
  auto args = std::make_shared<MergeArgs>();
  auto* sub = app.add_subcommand(
      "merge",
      "Join the partial results of one run (`microsim trace vndf --shard K/N` histograms; `microsim trace masking "
      "--surface S --shard K/N`, `microsim validate ... --shard K/N` or `microsim stability --shard K/N` JSON parts; "
      "`microsim scatter --shard K/N` scatter files; or a run interrupted part way) into the whole run: the same histogram EXR or JSON report, and the same "
      "table, as the single run, bit for bit. The parts must be of one run and "
      "hold every block exactly once (missing or repeated block ranges are named). Exit 0 merged (trace masking: "
      "1 if the merged leak test failed; validate, stability: 1 if the merged run rejects, as the single run), 2 bad "
      "input (nothing written).");
  sub->add_option("parts", args->parts,
                  "partial results of one run, in any order: histograms (EXR) or JSON parts (trace masking, validate, "
                  "stability)")
      ->required();
  sub->add_option("--out", args->out, "trace vndf, scatter: the merged histogram EXR to write (required)");
  sub->add_option("--json", args->json,
                  "write the JSON report (trace vndf: also; trace masking: the merged report; validate, stability: "
                  "the report the single run's --json is)");
  sub->add_option("--surface", args->surface,
                  "heightfield runs: the heightmap the parts were traced on (default: the path they record)");
  on_selected(sub, [args] { return run_merge(*args); });
}};

}  // namespace
}  // namespace microsim::app
