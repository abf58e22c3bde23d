#include "merge_scatter.h"

#include "command.h"
#include "scatter_report.h"

#include "microgeom/exr_io.h"
#include "stats/scatter_merge.h"

#include <fmt/core.h>

#include <filesystem>
#include <map>

namespace microsim::app {

namespace {

ScatterFile read_scatter_part(const std::string& path) {
  if (!std::filesystem::exists(path)) throw UsageError(fmt::format("part '{}': no such file", path));
  try {
    const microgeom::ExrImage image = microgeom::read_exr(path);
    if (!is_scatter_image(image))
      throw UsageError(fmt::format("cannot merge: part '{}' is not a scatter file (microsim scatter --shard) but the "
                                   "first part is: parts of one run are of one kind", path));
    ScatterFile f = scatter_from_exr(image, path);
    if (f.kind != ScatterFileKind::histogram)
      throw UsageError(fmt::format("cannot merge: part '{}' is an expectation (microsim scatter --model analytic), "
                                   "not part of a sampled run", path));
    return f;
  } catch (const ScatterIoError& e) {
    throw UsageError(e.what());
  } catch (const std::runtime_error& e) {  // not an EXR file (UsageError is no runtime_error of the reader's)
    if (dynamic_cast<const UsageError*>(&e)) throw;
    throw UsageError(fmt::format("part '{}': {}", path, e.what()));
  }
}

}  // namespace

bool is_scatter_part(const std::string& path) {
  if (std::filesystem::path(path).extension() == ".json" || !std::filesystem::exists(path)) return false;
  try {
    return is_scatter_image(microgeom::read_exr(path));
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    return false;  // read_parts names what is wrong with it
  }
}

int merge_scatter(const std::vector<std::string>& paths, const std::string& out, const std::string& json,
                  const std::string& surface) {
  if (!surface.empty()) throw UsageError("--surface applies to trace vndf and trace masking parts only");
  if (out.empty()) throw UsageError("--out MERGED.exr is required to merge scatter parts");
  if (std::filesystem::path(out).extension() != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", out));
  check_output("--out", out);
  check_output("--json", json);
  std::vector<ScatterHistogram> parts;
  std::map<std::string, std::string> notes;
  for (const std::string& path : paths) {
    ScatterFile f = read_scatter_part(path);
    if (parts.empty()) notes = f.notes;
    else if (f.notes != notes)
      throw UsageError(fmt::format("cannot merge: part '{}' records other notes than part '{}' (another run)", path,
                                   paths.front()));
    parts.push_back(std::move(f.histogram));
  }
  ScatterHistogram merged;
  try {
    merged = merge_scatter_parts(parts);
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
  fmt::print(stderr, "merge: {} scatter parts, {} paths, blocks {}\n", parts.size(), merged.paths(),
             merged.provenance.blocks.to_string());
  return report_scatter(merged, notes, {out, json});
}

}  // namespace microsim::app
