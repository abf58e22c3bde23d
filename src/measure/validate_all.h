// measure: `microsim validate --all` as a library call: every sampler of the zoo over the standard grid
// (zoo_cases), then the BSDF samplers over theirs (bsdf_zoo_cases), each validation at its Sidak share of
// the family-wise level, and the batch's verdict: pass when every correct sampler passes every validation
// and every negative control is rejected with p < kNegativeControlP wherever its bug has an effect. The
// command line renders the rows as they come (ZooObserver) and the result; Python returns it.
#pragma once

#include "measure/validation.h"
#include "stats/histogram_io.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

inline constexpr double kNegativeControlP = 1e-6;  // a negative control must be rejected with p below this

// One validation of the batch, as a row of its verdict table.
struct ZooRow {
  bool bsdf = false;  // a row of the BSDF section
  std::string sampler;
  bool negative_control = false;
  double alpha_x = 0, alpha_y = 0, theta_deg = 0, phi_deg = 0;
  bool inside = false;          // BSDF: a dielectric seen from inside
  bool bug_has_effect = false;  // BSDF: a negative control whose bug the samples can see here
  std::string material;         // BSDF: the material's description
  std::string verdict;          // "pass", "FAIL", "rejected" (a negative control), "no effect" (its bug has none here)
  ValidationReport report;
};

// A sampler's validations together: its line of the summary.
struct ZooSummaryRow {
  std::string sampler;
  bool negative_control = false;
  int total = 0, passed = 0;
  int without_effect = 0;  // BSDF negative controls: validations where the bug changes nothing
  double min_p = 1, max_p = 0, seconds = 0;
  bool expectation_met = true;  // correct: all pass; negative control: all rejected with p < kNegativeControlP
};

struct ZooResult {
  std::vector<ZooRow> rows;              // in the batch's order: the direction zoo, then the BSDF section
  std::vector<ZooSummaryRow> summary;    // the samplers that ran, in the registries' order
  bool partial = false;                  // cancelled: no verdict
  bool all_met = false;                  // every sampler met its expectation (false when partial)
  std::size_t requested = 0;             // validations requested (done: rows.size())
  double seconds = 0;                    // wall time of the batch
  int references = 0;                    // claimed pdfs integrated (x 2 binnings) for the direction zoo
  double reference_seconds = 0;
  int bsdf_references = 0;               // and for the BSDF section
  double bsdf_reference_seconds = 0;
  // The run it is of (what its JSON records).
  std::uint64_t samples = 0, seed = 1;
  Precision precision = Precision::float64;
  double significance = 0.01, per_validation_significance = 0;

  // "pass", "fail" or "interrupted".
  std::string verdict() const { return partial ? "interrupted" : all_met ? "pass" : "fail"; }
};

// What a caller sees as the batch runs (each may be empty; called on the calling thread).
struct ZooObserver {
  std::function<void(const ZooRow&)> row;                    // a validation done
  std::function<void(std::size_t validations)> bsdf_section;  // the BSDF section begins
};

// The references of the direction zoo: one per configuration and claimed pdf, shared by the samplers that
// claim it (the configurations come in order; a reference is kept while its configuration lasts).
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

// The references of the BSDF section: one per configuration and material, shared by its samplers, all
// computed up front (prepare).
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

// The batch's rows and summary as its validations come (also fed from merged parts: `microsim merge`).
class ZooBatch {
public:
  explicit ZooBatch(const ValidationRun& run);
  const ZooRow& add(const ValidationCase& c, ValidationReport report);
  void begin_bsdf_section(std::size_t validations);
  const ZooRow& add_bsdf(const BsdfValidationCase& c, ValidationReport report);
  ZooResult finish(bool partial, const ZooReferences& references, const BsdfZooReferences* bsdf_references);

private:
  ZooSummaryRow& summary_of(const std::string& sampler, bool negative_control);
  ZooResult result_;
  std::map<std::string, ZooSummaryRow> summary_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// The BSDF samplers of the zoo over their grid at the run's sample count and rows, the section at the
// family-wise level run.family_significance on its own (Sidak over its validations), seeds from run.seed.
// A batch's merge runs it too (it is not sharded), so that the merged result is the single run's. False
// when run.options.run was cancelled.
bool run_bsdf_section(const ValidationRun& run, ZooBatch& batch, BsdfZooReferences& references,
                      const ZooObserver& observer = {});

// The whole batch (run: batch = true, cases = zoo_cases(seed), as the command line builds it). Cancelled
// through run.options.run between validations (the result is then partial); progress there: stages
// "validate --all" and "validate --all: BSDF samplers", validations done of the stage's total. Throws
// InsufficientData when run.options.samples is too few for the tests.
ZooResult validate_all(const ValidationRun& run, const ZooObserver& observer = {});

// The result as `validate --all --json` writes it: verdict, counts, the run, "summary" and "results".
nlohmann::json to_json(const ZooResult& result);
// The command line's exit code of a result: 0 pass, 1 fail, 130 interrupted.
int exit_code(const ZooResult& result);

// ---- the merge of a validate run's parts ------------------------------------------------------------------------

// The merged parts of a validate run (measure/merge.h) analysed as the single run is: one validation's
// report, against its claimed pdf or against the traced histogram its parameters name (run.against, which
// must hold the counts the parts were compared with), or the batch's result with its BSDF section run here
// (it is not sharded; `control` reports its progress and cancels it, `observer` sees each row).
struct MergedValidation {
  ValidationRun run;
  std::optional<ValidationReport> report;  // one validation
  std::optional<TracedHistogram> traced;   // its oracle, when against a traced histogram
  std::optional<ZooResult> batch;          // --all
};
// Throws HistogramMergeError (parameters that describe no run, a histogram other than the parts'),
// HistogramIoError (the histogram unreadable) and InsufficientData (too few samples for the tests).
MergedValidation analyse_merged_validation(const ValidationPart& merged, const RunControl& control,
                                           const ZooObserver& observer = {});
// What `validate --json` writes for it: the report (against a histogram: its path, rays and hits too), or
// the batch's (to_json).
nlohmann::json merged_validation_json(const MergedValidation& m);

}  // namespace microsim
