// experiment: a run's directory (`microsim run SPEC --out DIR`): what is written there and how a rerun finds
// what was done.
//   results.json   the document (run_document): the command, version, spec (name, source, digest, canonical
//                  content), seed, plan, results (with each walk round's table and each partial VNDF round's
//                  blocks: what a resumed run continues from), partial;
//   index.html     the report (report.h), self-contained;
//   albedo-K.csv   measurement K's albedo table;
//   vndf-K.exr     measurement K's summed VNDF counts (stats/histogram_io.h, readable by `microsim plot` and
//                  `microsim validate --against`).
// Every file is written atomically (core/atomic_file.h), results.json and index.html last: an interrupted write
// leaves the previous complete files. A rerun of the same command reads the directory back (load_previous_run)
// and run_experiment (run.h) continues from it.
#pragma once

#include "experiment/run.h"
#include "experiment/spec.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace microsim::experiment {

struct RunIdentity {
  std::string command;  // the command line that reproduces the run
  std::string version;
  std::uint64_t seed = 0;  // the seed the run used (the spec's unless overridden)
  nlohmann::json inputs;   // input_digests(spec) when the run started: results.json's spec.inputs
};

// The content digest (FNV-1a, 16 hex digits; "" when unreadable) of each file the spec reads beyond itself (a dump,
// an eval file, a plugin, a heightmap), by key: taken once when a run starts, recorded, and compared on resume.
nlohmann::json input_digests(const ExperimentSpec& spec);

// The spec's identity in a document: name, source, digest, canonical content.
nlohmann::json spec_identity_json(const ExperimentSpec& spec);

// results.json's content.
nlohmann::json run_document(const ExperimentSpec& spec, const ExperimentPlan& plan, const ExperimentResults& results,
                            const RunIdentity& identity);

// Writes the directory's files (created if missing). Throws FileWriteError, HistogramIoError.
void write_run_directory(const std::filesystem::path& dir, const ExperimentSpec& spec, const ExperimentPlan& plan,
                         const ExperimentResults& results, const RunIdentity& identity);

// What an earlier run of this spec and seed left in DIR: its plan and results (the VNDF counts read back
// from vndf-K.exr).
struct PreviousRun {
  ExperimentPlan plan;
  ExperimentResults results;
};

// nullopt when DIR does not exist or is empty: a fresh run. Throws std::invalid_argument (bad usage: nothing
// is run or written) when DIR is not a directory, holds files but no results.json, holds another spec's
// results (digest), or this spec's run with another seed (the message names both and says what to do), or a
// run of input files whose content has changed since (`inputs`: input_digests(spec) now; the message names the
// key), or when results.json or a histogram cannot be read.
std::optional<PreviousRun> load_previous_run(const std::filesystem::path& dir, const ExperimentSpec& spec,
                                             std::uint64_t seed, const nlohmann::json& inputs);

}  // namespace microsim::experiment
