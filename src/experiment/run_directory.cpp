// experiment: a run's directory: writing it, reading it back (run_directory.h).
#include "experiment/run_directory.h"

#include "core/atomic_file.h"
#include "core/fnv1a.h"
#include "core/parse.h"
#include "experiment/measurement.h"
#include "experiment/report.h"
#include "stats/histogram_io.h"
#include "stats/scatter_io.h"

#include <fmt/core.h>

#include <fstream>
#include <stdexcept>

namespace microsim::experiment {
namespace {

namespace fs = std::filesystem;

// A measurement's file: KIND-K.EXT (vndf-3.exr, validation-4.exr, scattering-5.exr, albedo-0.csv).
fs::path measurement_file(const fs::path& dir, const ExperimentSpec& spec, const MeasurementResult& m, std::size_t index,
                          const char* extension) {
  return dir / fmt::format("{}-{}.{}", to_string(spec.quantities.at(m.decision.quantity).kind), index, extension);
}

nlohmann::json read_document(const fs::path& path) {
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    throw std::invalid_argument(fmt::format("{}: not a results.json (cannot be parsed): refusing to write over it", quote_excerpt(path.string())));
  return j;
}

std::string text_member(const nlohmann::json& j, const char* object, const char* key) {
  if (!j.contains(object) || !j[object].is_object() || !j[object].contains(key) || !j[object][key].is_string())
    return "";
  return j[object][key].get<std::string>();
}

// FNV-1a of a file's bytes, 16 hex digits ("" when it cannot be read: the run reports that itself).
std::string file_digest(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::uint64_t h = kFnv1aOffset;
  std::vector<char> buffer(1 << 16);
  while (in.read(buffer.data(), std::streamsize(buffer.size())) || in.gcount() > 0)
    h = fnv1a(h, buffer.data(), std::size_t(in.gcount()));
  return fmt::format("{:016x}", h);
}

// A file the spec reads whose content changed since the document was written: its results are not this file's.
void check_same_inputs(const fs::path& dir, const nlohmann::json& doc, const ExperimentSpec& spec,
                       const nlohmann::json& inputs) {
  if (!doc["spec"].contains("inputs") || !doc["spec"]["inputs"].is_object()) return;
  const nlohmann::json& recorded = doc["spec"]["inputs"];
  for (const PathOption& f : spec_input_files(spec)) {
    if (f.option == "SPEC" || !recorded.contains(f.option) || !recorded[f.option].is_string()) continue;
    const std::string now = inputs.value(f.option, "");
    if (recorded[f.option].get<std::string>() != now)
      throw std::invalid_argument(fmt::format(
          "--out {}: {} ({}) changed since that run (content digest {}, now {}): its results are not this file's; "
          "use another --out to measure it",
          quote_excerpt(dir.string()), f.option, quote_excerpt(f.path.string()), recorded[f.option].get<std::string>(), now));
  }
}

// The document must be this spec's, at this seed, with the same input files.
void check_same_run(const fs::path& dir, const nlohmann::json& doc, const ExperimentSpec& spec, std::uint64_t seed,
                    const nlohmann::json& inputs) {
  const std::string digest = text_member(doc, "spec", "digest");
  if (digest != spec_digest(spec))
    throw std::invalid_argument(fmt::format("--out {}: holds the results of another spec (digest '{}', this spec's {}): "
                                            "refusing to overwrite them; use another --out",
                                            quote_excerpt(dir.string()), digest, spec_digest(spec)));
  const auto recorded = doc.contains("seed") && doc["seed"].is_number_unsigned() ? doc["seed"].get<std::uint64_t>() : 0;
  if (recorded != seed)
    throw std::invalid_argument(fmt::format("--out {}: holds this spec's run with seed {}, this run's seed is {}: "
                                            "refusing to mix them; rerun with --seed {} to resume it, or use another --out",
                                            quote_excerpt(dir.string()), recorded, seed, recorded));
  check_same_inputs(dir, doc, spec, inputs);
}

// The counts and sums of the measurements that have them, read back into the results (each kind's read_back).
void read_histograms(const fs::path& dir, const ExperimentSpec& spec, ExperimentResults& results) {
  for (std::size_t i = 0; i < results.measurements.size(); ++i) {
    MeasurementResult& m = results.measurements[i];
    if (!m.ran || m.rounds.empty() || !m.values.is_object()) continue;
    try {
      make_measurement(spec, m.decision)->read_back(measurement_file(dir, spec, m, i, "exr"), m);
    } catch (const HistogramIoError& e) {
      throw std::invalid_argument(fmt::format("cannot resume measurement {}: {}", i, e.what()));
    } catch (const ScatterIoError& e) {
      throw std::invalid_argument(fmt::format("cannot resume measurement {}: {}", i, e.what()));
    }
  }
}

// Empty, or holding only the surface cache (DIR/surfaces: a plan interrupted after building a surface).
bool holds_only_surfaces(const fs::path& dir) {
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    if (e.path().filename() != "surfaces" || !e.is_directory()) return false;
  return true;
}

}  // namespace

nlohmann::json input_digests(const ExperimentSpec& spec) {
  nlohmann::json j = nlohmann::json::object();
  for (const PathOption& f : spec_input_files(spec))
    if (f.option != "SPEC") j[f.option] = file_digest(f.path);
  return j;
}

nlohmann::json spec_identity_json(const ExperimentSpec& spec) {
  return {{"name", spec.name},
          {"source", spec.source},
          {"digest", spec_digest(spec)},
          {"canonical", nlohmann::json::parse(canonical_spec(spec))}};
}

nlohmann::json run_document(const ExperimentSpec& spec, const ExperimentPlan& plan, const ExperimentResults& results,
                            const RunIdentity& identity) {
  nlohmann::json spec_json = spec_identity_json(spec);
  spec_json["inputs"] = identity.inputs;
  return {{"command", identity.command},
          {"version", identity.version},
          {"spec", std::move(spec_json)},
          {"seed", identity.seed},
          {"plan", plan_json(plan, spec)},
          {"results", results_json(results)},
          {"partial", results.partial}};
}

void write_run_directory(const fs::path& dir, const ExperimentSpec& spec, const ExperimentPlan& plan,
                         const ExperimentResults& results, const RunIdentity& identity) {
  fs::create_directories(dir);
  ReportHistograms histograms;
  ReportScatters scatters;
  for (std::size_t i = 0; i < results.measurements.size(); ++i) {
    const MeasurementResult& m = results.measurements[i];
    if (!m.csv.empty()) write_file_atomically(measurement_file(dir, spec, m, i, "csv"), m.csv);
    if (m.scatter.paths() > 0) {
      write_scatter_exr(measurement_file(dir, spec, m, i, "exr"), m.scatter, {{"measurement", m.decision.label}});
      scatters.emplace(i, ScatterFile{ScatterFileKind::histogram, m.scatter, {}, {}});
    }
    if (m.expectation.bins() > 0) {
      write_scatter_exr(measurement_file(dir, spec, m, i, "exr"), m.expectation, {{"measurement", m.decision.label}});
      scatters.emplace(i, ScatterFile{ScatterFileKind::expectation, {}, m.expectation, {}});
    }
    if (m.histogram.binnings.empty()) continue;
    TracedHistogram h = m.histogram;
    h.partial = m.partial;
    write_histogram_exr(measurement_file(dir, spec, m, i, "exr"), h);
    histograms.emplace(i, std::move(h));
  }
  const nlohmann::json doc = run_document(spec, plan, results, identity);
  write_file_atomically(dir / "results.json", doc.dump(2) + "\n");
  write_file_atomically(dir / "index.html", experiment_report_html(doc, histograms, scatters));
}

std::optional<PreviousRun> load_previous_run(const fs::path& dir, const ExperimentSpec& spec, std::uint64_t seed,
                                             const nlohmann::json& inputs) {
  if (!fs::exists(dir)) {
    const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
    if (!fs::is_directory(parent)) throw std::invalid_argument(fmt::format("--out {}: its parent is not a directory", quote_excerpt(dir.string())));
    return std::nullopt;
  }
  if (!fs::is_directory(dir)) throw std::invalid_argument(fmt::format("--out {}: not a directory", quote_excerpt(dir.string())));
  if (holds_only_surfaces(dir)) return std::nullopt;
  if (!fs::exists(dir / "results.json"))
    throw std::invalid_argument(fmt::format("--out {}: not empty and holds no results.json: refusing to write into it", quote_excerpt(dir.string())));
  const nlohmann::json doc = read_document(dir / "results.json");
  check_same_run(dir, doc, spec, seed, inputs);
  PreviousRun previous;
  previous.plan = plan_from_json(doc.value("plan", nlohmann::json::object()), spec);
  previous.results = results_from_json(doc.value("results", nlohmann::json::object()), previous.plan);
  read_histograms(dir, spec, previous.results);
  return previous;
}

}  // namespace microsim::experiment
