// run_experiment's resumption and the planner's honesty, on tiny specs (library level, seconds):
//   - a run cancelled part way (a VNDF round cut in its blocks; a walk albedo after its first round; a walk of
//     per-order lobes cut in its blocks), written
//     to JSON and read back as an interrupted run leaves it, then resumed: the same values as the
//     uninterrupted run of that seed, bit for bit (timings aside); a resumed run with another plan's counts
//     differs (negative control: the comparison can fail);
//   - the honesty check: a VNDF at 4x the planned cost, another seed, is within the target TV of
//     the planned run; at 1/16 of the planned cost it is not (the check can fail).
#include "experiment/plan.h"
#include "experiment/run.h"
#include "small_pilots.h"

#include <gtest/gtest.h>

#include <atomic>
#include <iostream>
#include <cmath>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_resume {

namespace {

using namespace microsim;
using namespace microsim::experiment;
using microsim::test::plan_with_small_pilots;

ExperimentSpec tiny_spec() {
  return parse_spec_toml(R"(
seed = 5
[[material]]
name = "m"
alphas = [0.5]
type = "mirror"
[[quantity]]
kind = "vndf"
material = "m"
theta = [40]
rows = 7
target_tv = 0.02
[[quantity]]
kind = "albedo"
material = "m"
orders = "all"
mus = 3
target_relative_error = 0.01
)", "tiny.toml");
}

// What a run measured, without its timings (which differ from run to run): the values and errors.
nlohmann::json measured(const ExperimentResults& results) {
  nlohmann::json out = nlohmann::json::array();
  for (const MeasurementResult& m : results.measurements) {
    nlohmann::json values = m.values;
    values.erase("seconds");
    values.erase("row_seconds");
    nlohmann::json rounds = nlohmann::json::array();
    for (const RoundRecord& r : m.rounds) rounds.push_back({r.units, r.seed, r.achieved, r.partial});
    out.push_back({{"values", values}, {"rounds", rounds}, {"achieved", m.achieved}, {"units", m.units}, {"met", m.met}});
  }
  return out;
}

// As an interrupted run leaves it: through results.json's JSON (the VNDF counts kept beside it).
ExperimentResults as_read_back(const ExperimentResults& results, const ExperimentPlan& plan) {
  ExperimentResults back = results_from_json(nlohmann::json::parse(results_json(results).dump()), plan);
  for (std::size_t i = 0; i < back.measurements.size(); ++i) back.measurements[i].histogram = results.measurements[i].histogram;
  return back;
}

// A cancel token set by the progress reports once `stage` has passed `fraction` of its total in its
// `occurrence`-th call sequence (a new sequence starts when the total changes).
struct CancelAt {
  CancelAt(std::string s, double f, int o) : stage(std::move(s)), fraction(f), occurrence(o) {}
  std::string stage;
  double fraction;
  int occurrence;
  CancelToken token;
  std::atomic<int> seen{0};
  std::atomic<std::uint64_t> last_total{0};
  RunControl control(int threads) {
    RunControl run;
    run.threads = threads;
    run.cancel = &token;
    run.progress = [this](std::string_view s, std::uint64_t done, std::uint64_t total) {
      if (s != stage) return;
      if (total != last_total.exchange(total)) seen.fetch_add(1);
      if (seen.load() >= occurrence && double(done) >= fraction * double(total)) token.cancel();
    };
    return run;
  }
};

ExperimentResults run_with(const ExperimentSpec& spec, const ExperimentPlan& plan, RunControl run, double cost = 1,
                           const ExperimentResults* resume = nullptr) {
  RunOptions o;
  o.run = std::move(run);
  o.cost_factor = cost;
  o.resume = resume;
  return run_experiment(spec, plan, o);
}

TEST(ExperimentResume, AnInterruptedVndfRoundResumesFromItsBlocksBitForBit) {
  const ExperimentSpec spec = tiny_spec();
  const ExperimentPlan plan = plan_with_small_pilots(spec);
  const ExperimentResults whole = run_with(spec, plan, RunControl{2, nullptr, {}});
  CancelAt cancel{"trace vndf", 0.4, 1};
  const ExperimentResults cut = run_with(spec, plan, cancel.control(2));
  ASSERT_TRUE(cut.partial);
  ASSERT_EQ(cut.measurements.size(), 1u);
  ASSERT_FALSE(cut.measurements[0].rounds.empty());
  EXPECT_TRUE(cut.measurements[0].rounds.back().partial);  // cut inside a round: its blocks are resumed
  EXPECT_LT(cut.measurements[0].units, whole.measurements[0].units);
  const ExperimentResults back = as_read_back(cut, plan);
  const ExperimentResults resumed = run_with(spec, plan, RunControl{1, nullptr, {}}, 1, &back);
  EXPECT_FALSE(resumed.partial);
  EXPECT_EQ(measured(resumed).dump(), measured(whole).dump());
  // Negative control: resumed with another seed (the cut round keeps its own; what follows is another run's),
  // the results differ.
  RunOptions other;
  other.seed = 1234;
  other.resume = &back;
  EXPECT_NE(measured(run_experiment(spec, plan, other)).dump(), measured(whole).dump());
}

TEST(ExperimentResume, AWalkCutAfterItsFirstRoundKeepsItAndRunsTheRest) {
  const ExperimentSpec spec = tiny_spec();
  const ExperimentPlan plan = plan_with_small_pilots(spec);
  // At a quarter of the planned paths the first round cannot meet the target: a second round follows.
  const ExperimentResults whole = run_with(spec, plan, RunControl{2, nullptr, {}}, 0.25);
  ASSERT_GE(whole.measurements[1].rounds.size(), 2u);
  CancelAt cancel{"albedo table", 0.5, 2};  // in the walk's second round
  const ExperimentResults cut = run_with(spec, plan, cancel.control(2), 0.25);
  ASSERT_TRUE(cut.partial);
  ASSERT_EQ(cut.measurements.size(), 2u);
  EXPECT_EQ(cut.measurements[1].rounds.size(), 1u);
  const ExperimentResults back = as_read_back(cut, plan);
  const ExperimentResults resumed = run_with(spec, plan, RunControl{2, nullptr, {}}, 0.25, &back);
  EXPECT_FALSE(resumed.partial);
  EXPECT_EQ(measured(resumed).dump(), measured(whole).dump());
}

TEST(ExperimentResume, AnInterruptedWalkOfPerOrderLobesResumesFromItsBlocksBitForBit) {
  const ExperimentSpec spec = parse_spec_toml(R"(
seed = 9
[[material]]
name = "glass"
alphas = [0.5]
type = "dielectric"
eta = 1.5
[[quantity]]
kind = "scattering"
material = "glass"
orders = "all"
theta = [40]
target_tv = 0.05
)", "glass.toml");
  const ExperimentPlan plan = plan_with_small_pilots(spec);
  ASSERT_EQ(plan.decisions.size(), 1u);
  ASSERT_TRUE(plan.decisions[0].runnable) << plan.decisions[0].not_runnable;
  const ExperimentResults whole = run_with(spec, plan, RunControl{2, nullptr, {}});
  ASSERT_TRUE(whole.measurements[0].met);
  EXPECT_GT(whole.measurements[0].units, 20000u);
  CancelAt cancel{"smith walk", 0.4, 1};
  const ExperimentResults cut = run_with(spec, plan, cancel.control(2));
  ASSERT_TRUE(cut.partial);
  ASSERT_FALSE(cut.measurements[0].rounds.empty());
  EXPECT_TRUE(cut.measurements[0].rounds.back().partial);
  ExperimentResults back = as_read_back(cut, plan);
  back.measurements[0].scatter = cut.measurements[0].scatter;
  const ExperimentResults resumed = run_with(spec, plan, RunControl{1, nullptr, {}}, 1, &back);
  EXPECT_FALSE(resumed.partial);
  EXPECT_EQ(measured(resumed).dump(), measured(whole).dump());
  for (int k = 0; k < kScatterOrderBins; ++k)  // every bin's sums, not only the summaries
    for (std::size_t b = 0; b < whole.measurements[0].scatter.bins(); ++b)
      EXPECT_EQ(resumed.measurements[0].scatter.histogram(0, k).weight(b), whole.measurements[0].scatter.histogram(0, k).weight(b));
}

// The TV distance between two VNDF measurements' normalised histograms, the largest over the binnings.
double tv_between(const MeasurementResult& a, const MeasurementResult& b) {
  double worst = 0;
  for (std::size_t k = 0; k < a.histogram.counts.size(); ++k) {
    double tv = 0;
    const double na = double(a.histogram.hits), nb = double(b.histogram.hits);
    for (std::size_t i = 0; i < a.histogram.counts[k].size(); ++i)
      tv += std::abs(double(a.histogram.counts[k][i]) / na - double(b.histogram.counts[k][i]) / nb);
    worst = std::max(worst, tv / 2);
  }
  return worst;
}

TEST(ExperimentHonesty, FourTimesThePlannedCostMovesTheVndfByLessThanTheTarget) {
  const ExperimentSpec spec = tiny_spec();
  ExperimentPlan plan = plan_with_small_pilots(spec);
  plan.decisions.resize(1);  // the VNDF
  const double target = spec.quantities[0].target;
  const ExperimentResults planned = run_with(spec, plan, RunControl{2, nullptr, {}});
  ASSERT_TRUE(planned.measurements[0].met);
  RunOptions o;
  o.seed = 77;  // an independent run
  o.cost_factor = 4;
  const ExperimentResults more = run_experiment(spec, plan, o);
  EXPECT_GE(more.measurements[0].units, 4 * plan.decisions[0].units);
  const double moved = tv_between(planned.measurements[0], more.measurements[0]);
  EXPECT_LE(moved, target);
  // Negative control: a run at 1/16 of the planned cost (one round: no sequential top-up) moves by more.
  RunOptions few;
  few.seed = 78;
  few.cost_factor = 1.0 / 16;
  few.max_rounds = 1;
  const MeasurementResult starved = run_experiment(spec, plan, few).measurements[0];
  EXPECT_FALSE(starved.met);
  const double starved_moved = tv_between(starved, more.measurements[0]);
  EXPECT_GT(starved_moved, target);
  std::cout << "TV to the 4x run: planned " << moved << ", 1/16 " << starved_moved << " (target " << target << ")\n";
}

}  // namespace

}  // namespace test_experiment_resume
