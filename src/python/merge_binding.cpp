// python: merge(), what `microsim merge` runs (measure/merge.h) for every kind of part, returned as the dict
// its --json writes, the merged histogram written to `out` as the command writes it. The outputs are checked
// first as the command checks them (core/output_paths.h): never one of the parts, writable.
#include "python/binding.h"

#include "core/atomic_file.h"
#include "core/output_paths.h"
#include "measure/albedo.h"
#include "measure/masking.h"
#include "measure/merge.h"
#include "measure/scatter.h"
#include "measure/validate_all.h"
#include "scatter/albedo_table_io.h"
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

struct MergeOutputs {
  std::string out, json, surface;  // "" for none; surface: the heightmap of heightfield parts
};

// The command's checks: no output is a part, the surface or the other output, each can be created, `out` is
// what the parts' kind writes (an .exr histogram for trace vndf and scatter parts, the table's .exr for albedo
// parts, nothing for the others),
// and `surface` applies to the kinds traced on a heightfield.
void check_outputs(PartKind kind, const std::vector<std::string>& parts, const MergeOutputs& o) {
  std::vector<PathOption> inputs;
  for (const std::string& p : parts) inputs.push_back({"part", p});
  inputs.push_back({"surface", o.surface});
  check_output_paths(inputs, {{"out", o.out}, {"json", o.json}});
  const bool histogram = kind == PartKind::vndf || kind == PartKind::scatter || kind == PartKind::albedo;
  if (!histogram && !o.out.empty())
    throw py::value_error("out '" + o.out + "': " + part_kind_name(kind) + " parts merge into a JSON report (json=...)");
  if (histogram && !o.out.empty() && std::filesystem::path(o.out).extension() != ".exr")
    throw py::value_error("out '" + o.out + "': must be an .exr file");
  if (!o.surface.empty() && kind != PartKind::vndf && kind != PartKind::masking)
    throw py::value_error(std::string("surface applies to trace vndf and trace masking parts, not to ") +
                          part_kind_name(kind) + " parts");
  for (const std::string& path : {o.out, o.json})
    if (!path.empty()) check_writable(path);
}

// The heightmap at `path` (ValueError naming it when missing or malformed).
microgeom::Heightfield load_surface(const std::string& path, std::optional<double> tile_size) {
  if (!std::filesystem::exists(path)) throw py::value_error("surface '" + path + "': no such file");
  try {
    return microgeom::load_heightmap_exr(path, tile_size);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw py::value_error(std::string("surface: ") + e.what());
  }
}

// The library's HistogramMergeError of the analysis as the command words it.
template <class F> auto merge_errors(F&& f) {
  try {
    return f();
  } catch (const HistogramMergeError& e) {
    throw py::value_error(std::string("cannot merge: ") + e.what());
  }
}

nlohmann::json vndf_report(MergedVndf m, const MergeOutputs& o) {
  const std::string surface = m.histogram.attributes["surface"];
  if (surface == "ellipsoid") {
    const MergedEllipsoid e = analyse_merged_ellipsoid(std::move(m));
    if (!o.out.empty()) write_histogram_exr(o.out, e.vndf.histogram);
    return ellipsoid_vndf_json(e.vndf, *e.target, o.out);
  }
  const microgeom::Heightfield field = load_surface(o.surface.empty() ? surface : o.surface, std::nullopt);
  const HeightfieldVndf h = analyse_heightfield_vndf(std::move(m.histogram), m.unbinned, field);
  if (!o.out.empty()) write_histogram_exr(o.out, h.histogram);
  return heightfield_vndf_json(h, field, o.out);
}

nlohmann::json masking_report(const MaskingPart& merged, const MergeOutputs& o) {
  const std::string path = o.surface.empty() ? merged.surface : o.surface;
  const microgeom::Heightfield field = load_surface(path, merged.tile_size);
  const MaskingSurface surface(field, path, merged.geometry, /*trace=*/false);
  return surface_masking_json(merge_errors([&] { return analyse_masking_part(merged, surface); }), surface);
}

nlohmann::json validation_report(const ValidationPart& merged, const RunControl& control) {
  try {
    return merged_validation_json(merge_errors([&] { return analyse_merged_validation(merged, control); }));
  } catch (const HistogramIoError& e) {
    throw py::value_error(std::string("the parts' --against: ") + e.what());
  }
}

// The merged run's report, its histogram written to `out` ("" for none). The GIL is released.
nlohmann::json merged_report(MergedRun run, const MergeOutputs& o, const RunControl& control) {
  switch (run.kind) {
    case PartKind::vndf: return vndf_report(std::get<MergedVndf>(std::move(run.result)), o);
    case PartKind::scatter: {
      const auto& m = std::get<MergedScatter>(run.result);
      if (!o.out.empty()) write_scatter_exr(o.out, m.histogram, m.notes);
      return scatter_report_json(scatter_summary_json(m.histogram), m.notes);
    }
    case PartKind::masking: return masking_report(std::get<MaskingPart>(run.result), o);
    case PartKind::validate: return validation_report(std::get<ValidationPart>(run.result), control);
    case PartKind::stability: return stability_table_json(std::get<StabilityTable>(run.result));
    case PartKind::albedo: {
      const auto& table = std::get<AlbedoTable>(run.result);
      if (!o.out.empty()) microgeom::write_exr(o.out, albedo_table_exr(table));
      return albedo_table_json(table);
    }
  }
  throw std::logic_error("merge: unknown part kind");
}

std::string optional_path(const py::object& p) { return p.is_none() ? "" : path_of(p); }

py::object merge_of(const std::vector<py::object>& part_paths, const py::object& out_path, const py::object& json_path,
                    const py::object& surface_path, const py::object& progress) {
  std::vector<std::string> parts;
  for (const py::object& p : part_paths) parts.push_back(path_of(p));
  if (parts.empty()) throw py::value_error("merge: no parts");
  const MergeOutputs o{optional_path(out_path), optional_path(json_path), optional_path(surface_path)};
  const PartKind kind = merge_kind(parts);  // MergeError (std::invalid_argument): ValueError
  check_outputs(kind, parts, o);
  nlohmann::json report;
  run_interruptible([&](const RunControl& control) { report = merged_report(merge_parts(kind, parts), o, control); },
                    progress);
  if (!o.json.empty()) write_file_atomically(o.json, report.dump(2) + "\n");
  return json_object(report);
}

}  // namespace

void bind_merge(py::module_& m) {
  using namespace pybind11::literals;
  m.def("merge", &merge_of, "parts"_a, py::kw_only(), "out"_a = py::none(), "json"_a = py::none(),
        "surface"_a = py::none(), "progress"_a = py::none(),
        R"(Joins the partial results of one run into the whole run (`microsim merge`), bit for bit.

parts: paths of the JSON parts, in any order, of `trace vndf --shard K/N` (ellipsoid or heightfield),
`scatter --shard K/N`, `trace masking --surface S --shard K/N`, `validate ... --shard K/N` or
`stability --shard K/N`. out: the merged histogram (.exr) to write (trace vndf, scatter); json: the report
to write; surface: the heightmap heightfield parts were traced on (default: the path they record).
Neither output may be one of the parts. progress: a callable progress(stage, done, total) for the BSDF
section a merged `validate --all` runs. Returns the dict `microsim merge --json` writes (but for the peak
memory). Parts of different runs, blocks missing or repeated, or an EXR part of an earlier version raise
ValueError naming the part and the block ranges; nothing is written.)");
}

}  // namespace microsim::python
