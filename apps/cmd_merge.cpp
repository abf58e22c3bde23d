// microsim merge: joins the partial results of one run (the JSON parts of `trace vndf --shard K/N`,
// `scatter --shard K/N`, `trace masking --surface S --shard K/N`, `validate ... --shard K/N`,
// `stability --shard K/N` and `albedo --model smith-walk --shard K/N`, told apart by their provenance's
// producer) into the whole run. Reading, checking and adding the parts is the library's (measure/merge.h);
// this front end checks the options each kind takes and reports the merged run as the single run does.
// The parts must come from the same run (every run attribute or parameter equal, same binnings, same seed)
// and together hold every block exactly once; the merged result, its analysis, JSON and table are those
// of the single run, bit for bit (counts are exact integers, sums exact fixed-point sums).
//
// Exit codes: 0 merged (1: the merged run rejects, as the single run would), 2 bad usage or input (parts
// of different runs, blocks missing or repeated: the ranges are named; nothing written).
#include "albedo_report.h"
#include "command.h"
#include "surface_input.h"
#include "masking_report.h"
#include "scatter_report.h"
#include "stability_report.h"
#include "validate_report.h"
#include "vndf_report.h"

#include "core/errors.h"
#include "core/output_paths.h"
#include "measure/merge.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct MergeArgs {
  std::vector<std::string> parts;
  std::string out, csv, json, surface;
};

// The library's merge, its MergeError bad input (exit 2, nothing written).
template <class F> auto usage_errors_of_merge(F&& f) {
  try {
    return f();
  } catch (const MergeError& e) {
    throw UsageError(e.what());
  }
}

// ---- the options each kind takes, checked before the parts are merged ---------------------------------------

void check_exr_out(const MergeArgs& a, const char* what) {
  if (a.out.empty()) throw UsageError(fmt::format("--out MERGED.exr is required to merge {}", what));
  if (std::filesystem::path(a.out).extension() != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  check_output("--out", a.out);
}

void check_options(PartKind kind, const MergeArgs& a) {
  const std::string producer = part_kind_name(kind);
  if (kind == PartKind::vndf) {
    check_exr_out(a, "trace vndf histograms");
  } else if (kind == PartKind::scatter || kind == PartKind::albedo) {
    if (!a.surface.empty()) throw UsageError("--surface applies to trace vndf and trace masking parts only");
    check_exr_out(a, kind == PartKind::scatter ? "scatter parts" : "albedo parts");
  } else {
    if (!a.out.empty())
      throw UsageError(fmt::format("--out '{}': {} parts merge into a JSON report (--json MERGED.json)", a.out, producer));
    if (kind != PartKind::masking && !a.surface.empty())
      throw UsageError(fmt::format("--surface applies to heightfield parts, not to {} parts", producer));
  }
  if (!a.csv.empty() && kind != PartKind::albedo) throw UsageError("--csv applies to albedo parts only");
  if (!a.csv.empty() && std::filesystem::path(a.csv).extension() != ".csv")
    throw UsageError(fmt::format("--csv '{}': must be a .csv file", a.csv));
  check_output("--csv", a.csv);
  check_output("--json", a.json);
}

// ---- the merged run reported as the single run reports it ---------------------------------------------------

int report_vndf(MergedVndf m, std::size_t parts, const MergeArgs& a) {
  fmt::print(stderr, "merge: {} parts, {} rays, blocks {}\n", parts, m.histogram.rays, m.histogram.attributes["blocks"]);
  const std::string surface = m.histogram.attributes["surface"];
  if (surface == "ellipsoid") {
    const MergedEllipsoid e = analyse_merged_ellipsoid(std::move(m));
    return report_ellipsoid_vndf(e.vndf, *e.target, {a.out, a.json});
  }
  const microgeom::Heightfield field = load_surface(a.surface.empty() ? surface : a.surface, std::nullopt);
  const HeightfieldVndf h = analyse_heightfield_vndf(std::move(m.histogram), m.unbinned, field);
  return report_heightfield_vndf(h, field, {a.out, a.json});
}

int report_masking(const MaskingPart& merged, std::size_t parts, const MergeArgs& a) {
  fmt::print(stderr, "merge: {} trace masking parts, {} samples, blocks {}\n", parts, merged.sums.samples,
             merged.provenance.blocks.to_string());
  const std::string path = a.surface.empty() ? merged.surface : a.surface;
  const microgeom::Heightfield field = load_surface(path, merged.tile_size);
  const MaskingSurface surface(field, path, merged.geometry, /*trace=*/false);
  const SurfaceMasking m = [&] {
    try {
      return analyse_masking_part(merged, surface);
    } catch (const HistogramMergeError& e) {
      throw UsageError(fmt::format("cannot merge: {}", e.what()));
    }
  }();
  return report_surface_masking(m, surface, {a.json});
}

int report_scatter_merge(const MergedScatter& m, std::size_t parts, const MergeArgs& a) {
  fmt::print(stderr, "merge: {} scatter parts, {} paths, blocks {}\n", parts, m.histogram.paths(),
             m.histogram.provenance.blocks.to_string());
  return report_scatter(m.histogram, m.notes, {a.out, a.json});
}

int report_albedo_merge(const AlbedoTable& table, std::size_t parts, const MergeArgs& a) {
  fmt::print(stderr, "merge: {} albedo parts, {} cells\n", parts, table.alphas.size() * table.mus.size());
  return report_albedo_table(table, {a.out, a.csv, a.json});
}

// ---- the command -----------------------------------------------------------------------------------------

int run_merge(const MergeArgs& a) {
  std::vector<PathOption> inputs;
  for (const std::string& p : a.parts) inputs.push_back({"part", p});
  inputs.push_back({"--surface", a.surface});
  check_distinct_outputs(inputs, {{"--out", a.out}, {"--csv", a.csv}, {"--json", a.json}});
  const PartKind kind = usage_errors_of_merge([&] { return merge_kind(a.parts); });
  check_options(kind, a);
  MergedRun run = usage_errors_of_merge([&] { return merge_parts(kind, a.parts); });
  switch (kind) {  // rendering only: the kind was decided by merge_kind
    case PartKind::vndf: return report_vndf(std::get<MergedVndf>(std::move(run.result)), run.parts, a);
    case PartKind::scatter: return report_scatter_merge(std::get<MergedScatter>(run.result), run.parts, a);
    case PartKind::masking: return report_masking(std::get<MaskingPart>(run.result), run.parts, a);
    case PartKind::validate: return report_merged_validation(std::get<ValidationPart>(run.result), run.parts, a.json);
    case PartKind::stability: return report_merged_stability(std::get<StabilityTable>(run.result), run.parts, a.json);
    case PartKind::albedo: return report_albedo_merge(std::get<AlbedoTable>(run.result), run.parts, a);
  }
  throw InternalError("merge: unknown part kind");
}

CommandRegistration merge_registration{"merge", [](CLI::App& app) {
  auto args = std::make_shared<MergeArgs>();
  auto* sub = app.add_subcommand(
      "merge",
      "Join the partial results of one run (the JSON parts of `microsim trace vndf --shard K/N`, `microsim scatter "
      "--shard K/N`, `microsim trace masking --surface S --shard K/N`, `microsim validate ... --shard K/N`, "
      "`microsim stability --shard K/N` or `microsim albedo --model smith-walk --shard K/N`) into the whole run: the same "
      "histogram EXR or JSON report, and the same table, as the single run, bit for bit. The parts must be of one run and "
      "hold every block exactly once (missing or repeated block ranges are named). Exit 0 merged (trace masking: "
      "1 if the merged leak test failed; validate, stability: 1 if the merged run rejects, as the single run), 2 bad "
      "input (nothing written; an EXR part of an earlier version: re-run its shard).");
  sub->add_option("parts", args->parts, "partial results of one run (JSON), in any order")->required();
  sub->add_option("--out", args->out, "trace vndf, scatter: the merged histogram EXR to write; albedo: the table's EXR "
                  "(required)");
  sub->add_option("--csv", args->csv, "albedo: also write the table as CSV");
  sub->add_option("--json", args->json,
                  "write the JSON report (trace vndf: also; trace masking: the merged report; validate, stability: "
                  "the report the single run's --json is; albedo: the table's JSON)");
  sub->add_option("--surface", args->surface,
                  "heightfield runs: the heightmap the parts were traced on (default: the path they record)");
  on_selected(sub, [args] { return run_merge(*args); });
}};

}  // namespace
}  // namespace microsim::app
