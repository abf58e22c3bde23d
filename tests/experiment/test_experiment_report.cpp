// The report of a run (experiment/report.h, run_directory.h) on a tiny spec: the page is self-contained (no
// script, no external resource), holds the plan's reasons and every measured value as report_number prints
// it, an inline SVG per figure; a document missing a member is refused; the line chart checks its input;
// an albedo table read back from its JSON is the same table, bit for bit; the run directory is written and
// read back as the same plan and results (the analytic order-1 lobes too), and another seed's or spec's run
// is refused. The run's verdict (verdict.h) is decided by the validations alone (pass, fail with the rejected
// names, incomplete when interrupted, none without a test), and the page shows it first, the rejected row in red.
#include "experiment/measures.h"
#include "experiment/report.h"
#include "experiment/run_directory.h"
#include "experiment/verdict.h"
#include "scatter/albedo_table_io.h"
#include "stats/curve_figure.h"

#include "stats/svg_parts.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_report {

namespace {

using namespace microsim;
using namespace microsim::experiment;
namespace fs = std::filesystem;

ExperimentSpec small_spec(double alpha) {
  return parse_spec_toml(fmt::format(R"(
name = "report-test"
[[material]]
name = "m"
alphas = [{}, 0.6]
type = "mirror"
[[quantity]]
kind = "albedo"
material = "m"
mus = 3
target_relative_error = 0.001
[[quantity]]
kind = "vndf"
material = "m"
theta = [30]
rows = 7
target_tv = 0.1
[[quantity]]
kind = "validation"
material = "m"
sampler = "heitz2018"
theta = [60]
rows = 7
detect_tv = 0.05
[[quantity]]
kind = "scattering"
material = "m"
theta = [20]
target_tv = 0.01
)", alpha), "small.toml");
}

struct SmallRun {
  ExperimentSpec spec = small_spec(0.3);
  ExperimentPlan plan;
  ExperimentResults results;
  SmallRun() {
    PlanOptions p;
    p.pilot_rays = 1 << 13;
    plan = plan_experiment(spec, p);
    results = run_experiment(spec, plan, RunOptions{});
  }
};

const SmallRun& small_run() {
  static const SmallRun run;
  return run;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ExperimentReport, ThePageIsSelfContainedAndHoldsEveryMeasuredValue) {
  const SmallRun& run = small_run();
  const nlohmann::json doc = run_document(run.spec, run.plan, run.results, {"microsim run small.toml --out x", "0.1", 1, {}});
  ReportHistograms histograms;
  for (std::size_t i = 0; i < run.results.measurements.size(); ++i)
    if (!run.results.measurements[i].histogram.binnings.empty()) histograms.emplace(i, run.results.measurements[i].histogram);
  ASSERT_EQ(histograms.size(), 4u);  // the VNDF and the validation at each alpha
  ReportScatters lobes;
  for (std::size_t i : {5u, 6u}) lobes.emplace(i, ScatterFile{ScatterFileKind::expectation, {}, run.results.measurements[i].expectation, {}});
  const std::string page = experiment_report_html(doc, histograms, lobes);
  EXPECT_EQ(page.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(count(page, "<script"), 0u);
  EXPECT_EQ(count(page, "http"), count(page, "xmlns=\"http://www.w3.org/2000/svg\""));  // namespaces only, no fetch
  // E1(mu) per alpha; a VNDF, a validation and an order-1 lobe figure per alpha
  EXPECT_EQ(count(page, "<svg"), 1u + 2u + 2u + 2u);
  EXPECT_EQ(count(page, "Sampler <b>heitz2018</b>"), 2u);
  EXPECT_NE(page.find("microsim run small.toml --out x"), std::string::npos);
  for (const MeasurementResult& m : run.results.measurements) {
    EXPECT_NE(page.find(svg::escape(m.decision.model.reason)), std::string::npos) << m.decision.label;
    EXPECT_NE(page.find("<b>" + report_number(m.achieved) + "</b>"), std::string::npos) << m.decision.label;
  }
  for (std::size_t i : {5u, 6u})  // the analytic lobes' albedos
    EXPECT_NE(page.find("albedo " + report_number(doc["results"]["measurements"][i]["values"]["analytic_scattering"]["albedo"]["value"])),
              std::string::npos);
  const nlohmann::json& e1 = doc["results"]["measurements"][0]["values"]["quantities"]["E1"];
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_NE(page.find("<b>" + report_number(e1["average"][a]) + "</b>"), std::string::npos);
    for (const auto& v : e1["value"][a]) EXPECT_NE(page.find(report_number(v) + " &plusmn;"), std::string::npos);
  }
  nlohmann::json broken = doc;
  broken.erase("plan");
  EXPECT_THROW(experiment_report_html(broken, histograms), std::invalid_argument);
}

// The index of the first validation measurement of the small run.
std::size_t first_validation(const ExperimentResults& results) {
  for (std::size_t i = 0; i < results.measurements.size(); ++i)
    if (results.measurements[i].values.contains("validation")) return i;
  return results.measurements.size();
}

// The page's body begins with the verdict's headline, of this class.
bool headline_first(const std::string& page, const std::string& verdict) {
  const std::size_t body = page.find("<body>\n");
  const std::string head = "<p id=\"verdict\" class=\"verdict " + verdict + "\">";
  return body != std::string::npos && page.compare(body + 7, head.size(), head) == 0;
}

TEST(ExperimentVerdict, TheValidationsAloneDecideItAndThePageShowsItFirst) {
  const SmallRun& run = small_run();
  const std::size_t k = first_validation(run.results);
  ASSERT_LT(k, run.results.measurements.size());
  const RunVerdict passed = run_verdict(run.results);  // heitz2018 at two alphas
  EXPECT_EQ(passed.verdict, Verdict::pass);
  EXPECT_EQ(passed.tested, 2u);
  EXPECT_TRUE(passed.rejected.empty());
  const RunIdentity id{"microsim run small.toml --out x", "0.1", 1, {}};
  EXPECT_TRUE(headline_first(experiment_report_html(run_document(run.spec, run.plan, run.results, id), {}), "pass"));
  // One validation's test rejected, its target met: the run fails, that measurement named and marked.
  ExperimentResults rejected = run.results;
  rejected.measurements[k].values["validation"]["verdict"] = "fail";
  ASSERT_TRUE(rejected.measurements[k].met);
  const RunVerdict failed = run_verdict(rejected);
  EXPECT_EQ(failed.verdict, Verdict::fail);
  EXPECT_EQ(failed.rejected, std::vector<std::string>{rejected.measurements[k].decision.label});
  const nlohmann::json doc = run_document(run.spec, run.plan, rejected, id);
  EXPECT_TRUE(doc["results"]["all_targets_met"].get<bool>());
  EXPECT_EQ(doc["results"]["verdict"], "fail");
  EXPECT_EQ(doc["results"]["rejected"], nlohmann::json::array({rejected.measurements[k].decision.label}));
  const std::string page = experiment_report_html(doc, {});
  EXPECT_TRUE(headline_first(page, "fail")) << page.substr(0, 2000);
  EXPECT_NE(page.find(fmt::format("<a href=\"#m{}\">{}</a>", k, svg::escape(failed.rejected[0]))), std::string::npos);
  EXPECT_EQ(count(page, "<td><span class=\"notmet\">rejected</span></td>"), 1u);
  // Interrupted: a rejection is final, otherwise the verdict waits for the rest.
  ExperimentResults cut = run.results;
  cut.partial = true;
  EXPECT_EQ(run_verdict(cut).verdict, Verdict::incomplete);
  rejected.partial = true;
  EXPECT_EQ(run_verdict(rejected).verdict, Verdict::fail);
  // A validation cut short tested nothing; without a validation there is no test at all.
  cut.measurements[k].partial = true;
  EXPECT_FALSE(validation_tested(cut.measurements[k]));
  ExperimentResults untested;
  for (const MeasurementResult& m : run.results.measurements)
    if (!m.values.contains("validation")) untested.measurements.push_back(m);
  EXPECT_EQ(run_verdict(untested).verdict, Verdict::none);
  EXPECT_EQ(run_verdict(untested).tested, 0u);
  EXPECT_TRUE(run_verdict(untested).untested.empty());
  // One validation passed and the other gave no verdict (its traced reference could not serve its samples) or
  // was not runnable: a test that did not run is not a pass, and the run names it.
  for (const bool runnable : {true, false}) {
    ExperimentResults half = run.results;
    MeasurementResult& m = half.measurements[k];
    ASSERT_TRUE(m.decision.tests);
    if (runnable) {
      m.values["validation"] = {{"verdict", "none"}, {"sampler", "heitz2018"}, {"samples", 4000},
                                {"no_verdict", "the reference serves 1000 samples"}, {"reference", "rays on a tile"}};
    } else {
      m.ran = false;
      m.values = nlohmann::json::object();
    }
    const RunVerdict v = run_verdict(half);
    EXPECT_EQ(v.verdict, Verdict::none) << runnable;
    EXPECT_EQ(v.tested, 1u);
    EXPECT_EQ(v.untested, std::vector<std::string>{m.decision.label});
    const nlohmann::json d = run_document(run.spec, run.plan, half, id);
    EXPECT_EQ(d["results"]["verdict"], "none");
    EXPECT_EQ(d["results"]["untested"], nlohmann::json::array({m.decision.label}));
    const std::string p = experiment_report_html(d, {});
    EXPECT_TRUE(headline_first(p, "none"));
    EXPECT_NE(p.find("could not give a verdict"), std::string::npos);
  }
}

TEST(ExperimentReport, CurveFigureChecksItsInput) {
  EXPECT_NE(curve_figure_svg("t", "s", {"x", "y"}, {{"a", {0, 1}, {1, 2}, {0.1, 0.1}}}).find("<polyline"), std::string::npos);
  EXPECT_THROW(curve_figure_svg("t", "s", {"x", "y"}, {{"a", {0, 1}, {1}, {}}}), std::invalid_argument);
  EXPECT_THROW(curve_figure_svg("t", "s", {"x", "y"}, {{"a", {0, 1}, {1, 2}, {0.1}}}), std::invalid_argument);
  EXPECT_THROW(curve_figure_svg("t", "s", {"x", "y"}, {}), std::invalid_argument);
}

TEST(ExperimentReport, AnAlbedoTableReadBackFromItsJsonIsTheSameTable) {
  AlbedoTableRequest r;
  r.model = AlbedoModel::smith_walk;
  r.alphas = {0.2, 0.7};
  r.mus = 3;
  r.paths = 2000;
  r.seed = 4;
  const AlbedoTable t = albedo_table(r);
  const AlbedoTable back = albedo_table_from_json(nlohmann::json::parse(albedo_table_json(t).dump()), r);
  EXPECT_EQ(albedo_table_json(back).dump(), albedo_table_json(t).dump());
  ASSERT_EQ(back.quantities.size(), t.quantities.size());
  for (std::size_t k = 0; k < t.quantities.size(); ++k)
    for (std::size_t i = 0; i < t.quantities[k].cells.size(); ++i) {
      EXPECT_EQ(back.quantities[k].cells[i].value, t.quantities[k].cells[i].value);
      EXPECT_EQ(back.quantities[k].cells[i].standard_error, t.quantities[k].cells[i].standard_error);
    }
  nlohmann::json broken = albedo_table_json(t);
  broken["quantities"]["E"]["value"][0].erase(0);
  EXPECT_THROW(albedo_table_from_json(broken, r), std::invalid_argument);
}

TEST(ExperimentReport, TheRunDirectoryReadsBackAsTheSameRunAndRefusesAnother) {
  const SmallRun& run = small_run();
  const fs::path dir = fs::temp_directory_path() / ("microsim_report_dir_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  EXPECT_FALSE(load_previous_run(dir, run.spec, 1, input_digests(run.spec)).has_value());
  write_run_directory(dir, run.spec, run.plan, run.results, {"cmd", "0.1", 1, {}});
  for (const char* f : {"results.json", "index.html", "albedo-0.csv", "vndf-1.exr", "vndf-2.exr", "validation-3.exr",
                        "validation-4.exr", "scattering-5.exr", "scattering-6.exr"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  const auto previous = load_previous_run(dir, run.spec, 1, input_digests(run.spec));
  ASSERT_TRUE(previous.has_value());
  EXPECT_EQ(plan_json(previous->plan, run.spec).dump(), plan_json(run.plan, run.spec).dump());
  EXPECT_EQ(results_json(previous->results).dump(), results_json(run.results).dump());
  for (std::size_t i : {1u, 3u})
    EXPECT_EQ(previous->results.measurements[i].histogram.counts, run.results.measurements[i].histogram.counts);
  for (std::size_t i : {5u, 6u}) {
    ASSERT_GT(run.results.measurements[i].expectation.bins(), 0u);
    EXPECT_EQ(previous->results.measurements[i].expectation.order1, run.results.measurements[i].expectation.order1);
  }
  EXPECT_THROW(load_previous_run(dir, run.spec, 2, input_digests(run.spec)), std::invalid_argument);             // another seed
  EXPECT_THROW(load_previous_run(dir, small_spec(0.35), 1, input_digests(small_spec(0.35))), std::invalid_argument);  // another spec
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_experiment_report
