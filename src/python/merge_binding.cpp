// python: merge(), what `microsim merge` runs (measure/merge.h), returned as the dict its --json writes, the
// merged histogram written to `out` as the command writes it. The outputs are checked first as the command
// checks them (core/output_paths.h): never one of the parts, writable.
#include "python/binding.h"

#include "core/atomic_file.h"
#include "core/output_paths.h"
#include "measure/merge.h"
#include "measure/scatter.h"
#include "stats/histogram_io.h"
#include "stats/scatter_io.h"
#include "validate/stability.h"

#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace microsim::python {

namespace {

std::string path_of(const py::handle& p) { return py::str(py::module_::import("os").attr("fspath")(p)); }

// The command's checks: no output is a part or the other output, each can be created, and `out` is what
// the parts' kind writes (an .exr histogram for trace vndf and scatter parts, nothing for JSON parts).
void check_outputs(PartKind kind, const std::vector<std::string>& parts, const std::string& out, const std::string& json) {
  std::vector<PathOption> inputs;
  for (const std::string& p : parts) inputs.push_back({"part", p});
  check_output_paths(inputs, {{"out", out}, {"json", json}});
  const bool histogram = kind == PartKind::vndf || kind == PartKind::scatter;
  if (!histogram && !out.empty())
    throw py::value_error("out '" + out + "': " + part_kind_name(kind) + " parts merge into a JSON report (json=...)");
  if (histogram && !out.empty() && std::filesystem::path(out).extension() != ".exr")
    throw py::value_error("out '" + out + "': must be an .exr file");
  for (const std::string& path : {out, json})
    if (!path.empty()) check_writable(path);
}

// The merged run's report and its histogram written to `out` ("" for none).
nlohmann::json merged_report(MergedRun run, const std::string& out) {
  switch (run.kind) {
    case PartKind::vndf: {
      auto& m = std::get<MergedVndf>(run.result);
      if (m.histogram.attributes["surface"] != "ellipsoid")
        throw py::value_error("heightfield trace vndf parts: not yet from Python (microsim merge --surface)");
      const MergedEllipsoid e = analyse_merged_ellipsoid(std::move(m));
      if (!out.empty()) write_histogram_exr(out, e.vndf.histogram);
      return ellipsoid_vndf_json(e.vndf, *e.target, out);
    }
    case PartKind::scatter: {
      const auto& m = std::get<MergedScatter>(run.result);
      if (!out.empty()) write_scatter_exr(out, m.histogram, m.notes);
      return scatter_report_json(scatter_summary_json(m.histogram), m.notes);
    }
    case PartKind::stability: return stability_table_json(std::get<StabilityTable>(run.result));
    default:
      throw py::value_error(std::string(part_kind_name(run.kind)) + " parts: not yet from Python (microsim merge)");
  }
}

py::object merge_of(const std::vector<py::object>& part_paths, const py::object& out_path, const py::object& json_path) {
  std::vector<std::string> parts;
  for (const py::object& p : part_paths) parts.push_back(path_of(p));
  if (parts.empty()) throw py::value_error("merge: no parts");
  const std::string out = out_path.is_none() ? "" : path_of(out_path);
  const std::string json = json_path.is_none() ? "" : path_of(json_path);
  const PartKind kind = merge_kind(parts);  // MergeError (std::invalid_argument): ValueError
  if (kind == PartKind::masking || kind == PartKind::validate)
    throw py::value_error(std::string(part_kind_name(kind)) + " parts: not yet from Python (microsim merge)");
  check_outputs(kind, parts, out, json);
  nlohmann::json report;
  {
    py::gil_scoped_release release;
    report = merged_report(merge_parts(kind, parts), out);
  }
  if (!json.empty()) write_file_atomically(json, report.dump(2) + "\n");
  return py::module_::import("json").attr("loads")(report.dump());
}

}  // namespace

void bind_merge(py::module_& m) {
  using namespace pybind11::literals;
  m.def("merge", &merge_of, "parts"_a, py::kw_only(), "out"_a = py::none(), "json"_a = py::none(),
        R"(Joins the partial results of one run into the whole run (`microsim merge`), bit for bit.

parts: paths of the parts, in any order: the histograms of `trace vndf --shard K/N` (on the ellipsoid), the
files of `scatter --shard K/N`, or the JSON parts of `stability --shard K/N`. out: the merged histogram
(.exr) to write (trace vndf, scatter); json: the report to write. Neither may be one of the parts.
Returns the dict `microsim merge --json` writes. Parts of different runs, or blocks missing or repeated,
raise ValueError naming the part and the block ranges; nothing is written.)");
}

}  // namespace microsim::python
