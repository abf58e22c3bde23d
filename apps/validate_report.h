// microsim CLI: the report of `microsim validate` (one validation, or the batch of --all), and the merge of
// its parts (`validate --shard K/N`, joined by `microsim merge`). One renderer, so a merged run prints and
// writes exactly what the single run would.
#pragma once

#include "measure/validation.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <map>
#include <memory>
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

// The references of the batch: one per configuration and claimed pdf, shared by the samplers that claim it
// (the configurations come in order; a reference is kept while its configuration lasts).
class ZooReferences {
public:
  std::shared_ptr<const ReferenceDistribution> get(const ValidationCase& c, int rows);
  int count() const { return count_; }
  double seconds() const { return seconds_; }

private:
  std::vector<double> configuration_;
  std::map<ClaimedPdf, std::shared_ptr<const ReferenceDistribution>> references_;
  int count_ = 0;
  double seconds_ = 0;
};

// The references of the BSDF section of the batch: one per configuration and material, shared by its
// samplers, all computed up front (prepare).
class BsdfZooReferences {
public:
  // Computes the references of all the cases, in parallel (each is one cubature, single-threaded).
  void prepare(const std::vector<BsdfValidationCase>& cases, int rows);
  const BsdfReference& get(const BsdfValidationCase& c) const;
  int count() const { return count_; }
  double seconds() const { return seconds_; }

private:
  static std::string key(const BsdfValidationCase& c);       // configuration and material
  static std::string flux_key(const BsdfValidationCase& c);  // and the sampler's convention
  std::map<std::string, BsdfReference> references_;          // by flux_key
  int count_ = 0;
  double seconds_ = 0;
};

// The batch as its validations come: the header at once, a row per validation (printed at once), then the
// summary per sampler, the overall verdict and the JSON.
class ZooReport {
public:
  explicit ZooReport(const ValidationRun& run);
  void add(const ValidationCase& c, const ValidationReport& report);
  // The BSDF section: its header, then a row per validation.
  void begin_bsdf_section(std::size_t validations);
  void add_bsdf(const BsdfValidationCase& c, const ValidationReport& report);
  // Returns the exit code: 130 when partial, 0 when every sampler met its expectation, 1 otherwise.
  int finish(bool partial, const ZooReferences& references, const std::string& json,
             const BsdfZooReferences* bsdf_references = nullptr);

private:
  struct Summary {
    int total = 0, passed = 0;
    double min_p = 1, max_p = 0, seconds = 0;
    bool expectation_met = true;  // correct: all pass; negative control: all rejected with p < 1e-6
    int without_effect = 0;       // BSDF negative controls: validations where the bug changes nothing
  };
  void print_summary_row(std::string_view name, bool negative_control, nlohmann::json& summary_json, bool& all_met) const;
  bool print_summary(nlohmann::json& summary_json) const;
  const ValidationRun& run_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  nlohmann::json results_ = nlohmann::json::array();
  std::map<std::string, Summary> summary_;
  std::size_t requested_ = 0;  // validations requested: the direction zoo's, then the BSDF section's
};

// The BSDF samplers of the zoo over their grid (bsdf_zoo_cases) at the run's sample count and rows, the
// section at the family-wise level run.family_significance on its own (Sidak over its validations), seeds
// from run.seed. A batch's merge runs it too (it is not sharded), so that the merged report is the single
// run's. False when interrupted.
bool run_bsdf_section(const ValidationRun& run, ZooReport& report, BsdfZooReferences& references);

// ---- merge -------------------------------------------------------------------------------------------------

// `microsim merge` of validate parts (their JSON, read from `paths`): the merged run's report, printed and
// written to `json` exactly as the single run writes it. UsageError when the parts do not make one run.
int merge_validation(const std::vector<nlohmann::json>& parts, const std::vector<std::string>& paths,
                     const std::string& json);

}  // namespace microsim::app
