// experiment: one measurement kind behind one interface. A kind (vndf, scattering, albedo, validation, masking, bsdf)
// says what it needs planned (its decisions), the first round the ranks or shards share, a part of a round (a
// block range run by a thread, an MPI rank or a job-array shard alike: split_rounds.h adds the parts in block
// order), its rounds against its target, and its values for results.json and resumption. The driver
// (run_experiment) owns the order of the measurements, resumption, cancellation, the ranks and the shards.
// A kind's MeasurementKind (below) holds the rest: its name, its spec keys, its model rule, its planner, its
// Measurement (make_measurement) and its report section; the registry's table is the only place that lists them.
#pragma once

#include "experiment/report.h"
#include "experiment/run.h"
#include "experiment/spec_tree.h"

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

namespace microsim::experiment {

// What a kind's rounds get from the driver.
struct RoundContext {
  const ExperimentSpec& spec;
  std::size_t index = 0;   // the decision's index in the plan (the ranks' and shards' name for it)
  std::uint64_t seed = 0;  // the run's
  const RunOptions& options;
  SurfaceCache& surfaces;
  RoundSplit split() const { return {options.ranks, options.stored}; }
  std::uint64_t round_seed(int round) const;
};

// The stream seed of round `round` of decision `index` (every round its own stream).
std::uint64_t round_seed(std::uint64_t seed, std::size_t index, int round);
// A first round's units: the planned ones times the cost factor, at least 1.
std::uint64_t first_units(const Decision& decision, double cost_factor);
// A first round of decision `index`: `units` in blocks of `block_size` from block 0, of round seed `round`.
RoundTask first_round_task(std::size_t index, std::uint64_t seed, std::uint64_t units, std::uint64_t block_size,
                           int round = 0);

// The round to run next of a histogram's rounds: a partial round of a resumed run from its first missing block,
// else a new round of at most `max_units` units.
struct RoundStart {
  std::uint64_t units = 0, first_block = 0, seed = 0, done = 0;  // done: units of the round already counted
  // The blocks to run: from first_block to the round's end (nullopt: the whole round).
  std::optional<BlockRange> blocks(std::uint64_t block_size) const;
};
// A measurement of one pass, not resumed (an interrupted one runs again whole): its rounds cleared, `pass` run
// (it records its round); a Cancelled from it leaves `m` partial.
void run_once(MeasurementResult& m, const std::function<void()>& pass);
// Rounds of at most `max_units` (each by `round`, false: nothing measured) until the target is met, the rounds
// run out or a round is cut short (a resumed run's partial round first).
void run_histogram_rounds(const RoundContext& context, MeasurementResult& m, std::uint64_t max_units,
                          const std::function<bool(const RoundStart&)>& round);

class Measurement {
public:
  Measurement(const ExperimentSpec& spec, const Decision& decision)
      : spec_(spec), decision_(decision), quantity_(spec.quantities.at(decision.quantity)) {}
  virtual ~Measurement() = default;
  Measurement(const Measurement&) = delete;
  Measurement& operator=(const Measurement&) = delete;

  // What `achieved` is (results.json's error_measure), and the target in its unit.
  virtual std::string error_measure() const = 0;
  virtual double target() const { return quantity_.target; }
  // Whether its rounds are block ranges split over ranks and shards, and whether the ranks share its work at all.
  virtual bool split() const { return false; }
  virtual bool shared() const { return split(); }
  // The first round as the ranks share it at the run's seed (shared() only).
  virtual RoundTask first_round(std::size_t index, std::uint64_t seed) const;
  // The tallies of blocks `mine` of `task` in this process, in the split's encoding (shared() only).
  virtual std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                           SurfaceCache& surfaces) const;
  // Its rounds, from `m` as the driver gives it (afresh, or an interrupted run's to continue).
  virtual void run(const RoundContext& context, MeasurementResult& m) const = 0;
  // What a resumed run continues from that results.json does not hold: read back from the run directory's
  // `exr` (KIND-K.exr, which run_directory.cpp wrote from m's histogram or scattering sums) into `m`, whose
  // values are the interrupted run's. Throws HistogramIoError or ScatterIoError. Nothing by default.
  virtual void read_back(const std::filesystem::path& exr, MeasurementResult& m) const;

protected:
  const SpecMaterial& material() const { return spec_.material(quantity_.material); }
  const ExperimentSpec& spec_;
  const Decision& decision_;
  const SpecQuantity& quantity_;
};

// The decisions a quantity of the kind needs (its pilots run), appended to `out`.
using PlanQuantity = void (*)(const ExperimentSpec& spec, std::size_t quantity, const PlanOptions& options,
                              SurfaceCache& surfaces, std::vector<Decision>& out);
// A kind's choice of model (choose_model asks the registry for the quantity's), and what the kinds share
// (plan_rules.cpp): a surface named in the spec is measured on it; Smith's model has single scattering in
// closed form and every order in the random walk (`note` appended to the reason).
using ModelRule = ModelChoice (*)(const SpecQuantity& quantity, const SpecMaterial& material);
ModelChoice explicit_surface_choice(const SpecQuantity& quantity);
ModelChoice smith_orders_choice(const SpecQuantity& quantity, const std::string& note);
// A kind's implementation of a decision (the decision's model chooses among its variants).
using MakeMeasurement = std::unique_ptr<Measurement> (*)(const ExperimentSpec& spec, const Decision& decision);
// A kind's section of one measurement's values in the report (`index` names its files, `label` titles its
// figures); "" when its values hold nothing to show (a measurement interrupted before its first round).
using KindReport = std::string (*)(const nlohmann::json& values, std::size_t index, const ReportHistograms& histograms,
                                   const ReportScatters& scatters, const std::string& label);

// The part of a round of rays traced on a decision's tile (measurement_vndf.cpp): a VNDF's on a tile, and
// the reference rays of a validation against a tile.
std::string tile_vndf_part(const ExperimentSpec& spec, const Decision& decision, const RoundTask& task,
                           const BlockRange& mine, const RunControl& run, SurfaceCache& surfaces);

// What a kind adds to the whole run (masking's over realisations): members of results.json's "results" derived
// from every measurement (not read back), and sections of the report (from results.json's document) before and
// after the measurements' own.
struct KindSummary {
  void (*results)(const std::vector<MeasurementResult>& measurements, nlohmann::json& results);
  std::string (*before)(const nlohmann::json& document);
  std::string (*after)(const nlohmann::json& document);
};

// A measurement kind: all that differs by kind, defined in the kind's own file (measurement_K.cpp, as
// `extern const MeasurementKind K_kind`) and listed once in the registry (measurement_registry.cpp), the only
// place that chooses by kind. A new kind is its file and its line there.
struct MeasurementKind {
  const char* name;         // the spec's `kind` (QuantityKind::name)
  const KindSpec* spec;     // its keys, their reader and its canonical keys
  bool views;               // its decisions are per alpha and view (results.json's decisions record both)
  ModelRule model;          // its cheapest sufficient model
  PlanQuantity plan;        // its decisions
  MakeMeasurement make;     // its Measurement of a decision
  KindReport report;        // its section of a measurement in the report
  const KindSummary* summary = nullptr;  // what it adds to the whole run (null: nothing)
  const char* test = nullptr;            // the member of its values that reports its test's verdict (null: none)
};

// The registry's answers (measurement_registry.cpp). make_measurement: `spec` and `decision` must outlive it.
// kind_has_views: its decisions are per alpha and view. The summaries: every kind's. kind_report: the kind's
// report section (its name as results.json's decisions give it), or null for a kind not in the registry.
std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision);
PlanQuantity quantity_planner(QuantityKind kind);
ModelRule kind_model_rule(QuantityKind kind);
bool kind_has_views(QuantityKind kind);
KindReport kind_report(const std::string& kind);
void add_kind_summaries(const std::vector<MeasurementResult>& measurements, nlohmann::json& results);
std::string kind_summary_sections(const nlohmann::json& document, bool before);
// The report of the test a measurement's values hold, whatever its kind (the registry names each testing kind's
// member of its values; its "verdict" is "pass" or "fail"), or null.
const nlohmann::json* kind_test_report(const nlohmann::json& values);
// Whether a kind tests something (a validation, a BSDF's battery): its quantities ask for a verdict.
bool kind_tests(QuantityKind kind);

}  // namespace microsim::experiment
