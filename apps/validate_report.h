// microsim CLI: the report of `microsim validate` (one validation, or the batch of --all), and the merge of
// its parts (`validate --shard K/N`, joined by `microsim merge`). One renderer, so a merged run prints and
// writes exactly what the single run would.
#pragma once

#include "measure/validate_all.h"
#include "measure/validation.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::app {

// How a single validation's report names what was validated: "sampler heitz2018", "samples from 'f.npy'",
// "... against 'h.exr' (N rays, H hits, quadric), two-sample chi-square".
std::string sampler_source(const SamplerInfo& sampler);
std::string oracle_source(const std::string& source, const std::string& oracle);
// The oracle a histogram file is: "'PATH' (N rays, H hits, TARGET)".
std::string histogram_oracle(const std::string& path, const TracedHistogram& traced);

struct ValidationOutputs {
  std::string json, plot;  // "" for none
};
// Prints the report, writes --json (with `extra` keys) and --plot; returns 0 pass, 1 rejected.
int report_validation(const ValidationReport& report, const std::string& source, const ValidationOutputs& outputs,
                      const nlohmann::json& extra = nlohmann::json::object());

// A traced histogram for --against (HIST.exr): a malformed file is bad usage; a partial trace is noted.
TracedHistogram read_oracle_histogram(const std::string& option, const std::string& path);

// ---- validate --all ----------------------------------------------------------------------------------------

// The rendering of the batch (measure/validate_all.h computes it): the header at once, a row per validation
// as it comes (observer()), then the summary per sampler, the overall verdict and the JSON (finish).
class ZooReport {
public:
  explicit ZooReport(const ValidationRun& run);
  // Prints each row as it comes, and the BSDF section's header.
  ZooObserver observer() const;
  // Prints the summary and the verdict, writes `json` (unless empty); returns the exit code: 130 when
  // partial, 0 when every sampler met its expectation, 1 otherwise.
  int finish(const ZooResult& result, const std::string& json) const;
};

// ---- merge -------------------------------------------------------------------------------------------------

// `microsim merge` of validate parts (merged by measure/merge.h from `parts` parts): the merged run's
// report, printed and written to `json` exactly as the single run writes it. UsageError when the parameters
// describe no run.
int report_merged_validation(const ValidationPart& merged, std::size_t parts, const std::string& json);

}  // namespace microsim::app
