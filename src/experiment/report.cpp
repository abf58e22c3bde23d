// experiment: the report page of a run (report.h).
#include "experiment/report.h"
#include "experiment/measurement.h"
#include "experiment/report_html.h"

#include "stats/curve_figure.h"
#include "stats/figure.h"
#include "stats/scatter_compare.h"
#include "stats/scatter_figure.h"
#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim::experiment {
namespace {

using namespace html;
constexpr const char* kStyle = R"(<style>
body{font-family:sans-serif;max-width:1400px;margin:1.5em auto;padding:0 1em;color:#222;line-height:1.4}
table{border-collapse:collapse;margin:0.6em 0 1.2em;font-size:13px}
th,td{border:1px solid #bbb;padding:3px 7px;text-align:left;vertical-align:top}
th{background:#eee} td.num{text-align:right;font-variant-numeric:tabular-nums}
.met{color:#060;font-weight:bold} .notmet{color:#a00;font-weight:bold}
.partial{background:#fff3cd;border:1px solid #d9b600;padding:0.5em 1em}
.verdict{font-size:1.3em;font-weight:bold;padding:0.5em 1em;border:2px solid #888}
.verdict.fail{color:#a00;border-color:#a00;background:#fdecea} .verdict.pass{color:#060;border-color:#060}
pre{background:#f6f6f6;padding:0.6em;overflow-x:auto;font-size:12px} figure{margin:0.5em 0;overflow-x:auto}
section.measurement{border-top:2px solid #999;margin-top:2em}
</style>
)";

// A measurement's badge: whether it ran enough samples, unless its test rejected (then "rejected", in red:
// a rejected validation is never shown as a success; its section says whether its target was met).
std::string met_text(bool ran, bool met, bool rejected = false) {
  if (!ran) return "not run";
  if (rejected) return R"(<span class="notmet">rejected</span>)";
  return met ? R"(<span class="met">met</span>)" : R"(<span class="notmet">NOT met</span>)";
}

// ---- the headline: the run's verdict (experiment/verdict.h), the first thing on the page -----------------

// Whether the measurement named `label` is one of results.rejected.
bool is_rejected(const json& doc, const json& label) {
  const json& rejected = member(member(doc, "results"), "rejected");
  return std::find(rejected.begin(), rejected.end(), label) != rejected.end();
}

// The rejected measurements, each a link to its section (#mK).
std::string rejected_links(const json& doc) {
  const json& measurements = member(member(doc, "results"), "measurements");
  std::vector<std::string> links;
  for (std::size_t i = 0; i < measurements.size(); ++i)
    if (is_rejected(doc, member(measurements[i], "measurement")))
      links.push_back(fmt::format("<a href=\"#m{}\">{}</a>", i, esc(text_of(measurements[i]["measurement"]))));
  return fmt::format("{}", fmt::join(links, ", "));
}

std::string verdict_headline(const json& doc) {
  const json& results = member(doc, "results");
  const std::string verdict = text_of(member(results, "verdict"));
  const std::string tested = text_of(member(results, "tested"));
  std::string text;
  if (verdict == "fail")
    text = fmt::format("Verdict: FAIL. Rejected: {} ({} of the {} statistical tests).",
                       rejected_links(doc), member(results, "rejected").size(), tested);
  else if (verdict == "pass")
    text = fmt::format("Verdict: pass. None of the {} statistical tests rejected.", tested);
  else if (verdict == "incomplete")
    text = "Verdict: incomplete. The run was interrupted before every measurement ran; no test rejected so far.";
  else if (results.contains("untested") && !results["untested"].empty())
    text = fmt::format("Verdict: none. {} statistical test(s) ran and none rejected, but {} could not give a verdict "
                       "(see their sections): {}. A test that did not run is not a pass.",
                       tested, results["untested"].size(),
                       esc(fmt::format("{}", fmt::join(results["untested"].get<std::vector<std::string>>(), ", "))));
  else
    text = "Verdict: none. No statistical test in this run (its measurements test nothing): nothing could reject.";
  return fmt::format("<p id=\"verdict\" class=\"verdict {}\">{}</p>\n", esc(verdict), text);
}

// ---- the head: status and how to reproduce -------------------------------------------------------------

std::string status_section(const json& doc) {
  const json& results = member(doc, "results");
  const bool partial = member(doc, "partial").get<bool>();
  std::string out = fmt::format("<h1>Experiment {}</h1>\n", esc(text_of(member(member(doc, "spec"), "name"))));
  if (partial)
    out += "<p class=\"partial\">PARTIAL: the run was interrupted; running it again (microsim run SPEC --out DIR) resumes it. "
           "The values below are what the completed rounds measured.</p>\n";
  out += fmt::format("<p>All targets met (enough samples; the verdict above says what the tests found): <b "
                     "id=\"all-targets-met\">{}</b>; run time {} s.</p>\n",
                     member(results, "all_targets_met").get<bool>() ? "yes" : "no",
                     report_number(member(results, "seconds")));
  const json& spec = member(doc, "spec");
  std::string body;
  body += row({"command", "<code>" + esc(text_of(member(doc, "command"))) + "</code>"});
  body += row({"version", esc(text_of(member(doc, "version")))});
  body += row({"seed", esc(text_of(member(doc, "seed")))});
  body += row({"spec", esc(text_of(member(spec, "source")))});
  body += row({"spec digest", "<code>" + esc(text_of(member(spec, "digest"))) + "</code>"});
  return out + "<h2>Reproduce</h2>\n" + table({}, body);
}

// ---- the plan --------------------------------------------------------------------------------------------

std::string count_text(const json& d) {
  const auto units = member(d, "units").get<std::uint64_t>();
  if (units == 0) return "-";
  return fmt::format("{} {}", units, text_of(member(d, "unit")));
}

std::string plan_section(const json& doc) {
  const json& plan = member(doc, "plan");
  std::string body;
  std::size_t i = 0;
  for (const json& d : member(plan, "decisions")) {
    const int cap = member(d, "order_cap").get<int>();
    body += row({std::to_string(i++), esc(text_of(member(d, "measurement"))), esc(text_of(member(d, "model"))),
                 esc(count_text(d)), cap > 0 ? std::to_string(cap) : "-",
                 report_number(member(d, "predicted_seconds")), member(d, "runnable").get<bool>() ? "yes" : "no"});
  }
  return fmt::format("<h2>Plan</h2>\n<p>Pilots took {} s; predicted run time {} s. Each measurement's reasons "
                     "are in its section below.</p>\n",
                     report_number(member(plan, "pilot_seconds")), report_number(member(plan, "predicted_seconds"))) +
         table({"#", "measurement", "model", "count", "order cap", "predicted s", "runnable"}, body);
}

// ---- the results summary ------------------------------------------------------------------------------------

std::string results_section(const json& doc) {
  std::string body;
  std::size_t i = 0;
  for (const json& m : member(member(doc, "results"), "measurements")) {
    const bool ran = member(m, "ran").get<bool>();
    const json& cost = member(m, "cost");
    body += row({std::to_string(i++), esc(text_of(member(m, "measurement"))), report_number(member(m, "target")),
                 ran ? report_number(member(m, "achieved")) : "-",
                 met_text(ran, member(m, "met").get<bool>(), is_rejected(doc, member(m, "measurement"))) +
                     (member(m, "partial").get<bool>() ? " (partial)" : ""),
                 std::to_string(member(m, "rounds").size()), esc(text_of(member(cost, "units"))),
                 report_number(member(cost, "seconds"))});
  }
  return "<h2>Results</h2>\n" +
         table({"#", "measurement", "target", "achieved", "met", "rounds", "units", "seconds"}, body);
}

// ---- one measurement ------------------------------------------------------------------------------------

// An explicit surface's decision: the tile, its predicted bias and why.
std::string surface_item(const json& s) {
  const bool assembly = text_of(member(s, "kind")) == "assembly";
  const double bias = member(s, "bias").get<double>();
  std::string files = text_of(member(s, "hash"));  // an albedo table's: one tile per alpha, comma-separated
  for (std::size_t i = files.find(','); i != std::string::npos; i = files.find(',', i + 15))
    files.replace(i, 1, ".exr, surfaces/");
  return fmt::format("<li><b>surface</b> {} {}{}, {}^2, l {} cells, NDF matched {}{}; predicted bias (TV) {}: {}</li>\n",
                     esc(text_of(member(s, "kind"))), esc(text_of(member(s, "name"))),
                     assembly ? " seed " + text_of(member(s, "seed")) : "", text_of(member(s, "resolution")),
                     report_number(member(s, "corr_cells")), esc(text_of(member(s, "ndf_match"))),
                     assembly ? ", cached as surfaces/" + esc(files) + ".exr" : "",
                     bias >= 0 ? report_number(bias) : "unknown", esc(text_of(member(s, "reason"))));
}

std::string decision_list(const json& d) {
  std::string out = "<ul>\n";
  out += fmt::format("<li><b>model</b> {}: {}</li>\n", esc(text_of(member(d, "model"))),
                     esc(text_of(member(d, "model_reason"))));
  out += fmt::format("<li><b>count</b> {}: {}</li>\n", esc(count_text(d)), esc(text_of(member(d, "count_reason"))));
  if (!member(d, "cap_reason").get<std::string>().empty())
    out += fmt::format("<li><b>order cap</b> {}: {}</li>\n", text_of(member(d, "order_cap")),
                       esc(text_of(member(d, "cap_reason"))));
  const json& pilot = member(d, "pilot");
  out += fmt::format("<li><b>pilot</b> {} units in {} s, error {}; predicted {} s</li>\n",
                     text_of(member(pilot, "units")), report_number(member(pilot, "seconds")),
                     report_number(member(pilot, "error")), report_number(member(d, "predicted_seconds")));
  if (d.contains("surface")) out += surface_item(d["surface"]);
  if (d.contains("not_runnable")) out += fmt::format("<li><b>not run</b>: {}</li>\n", esc(text_of(d["not_runnable"])));
  return out + "</ul>\n";
}

std::string rounds_table(const json& m) {
  std::string body;
  std::size_t i = 0;
  for (const json& r : member(m, "rounds")) {
    const double tolerance = member(r, "tolerance").get<double>();
    body += row({std::to_string(i++), text_of(member(r, "units")), text_of(member(r, "seed")),
                 tolerance > 0 ? report_number(tolerance) : "-", report_number(member(r, "seconds")),
                 report_number(member(r, "achieved"))});
  }
  return table({"round", "units", "seed", "tolerance", "seconds", "error after it"}, body);
}

// The kind's section of its values (kind_report: the registry's choice).
std::string measurement_values(const json& d, const json& values, std::size_t index, const ReportHistograms& histograms,
                               const ReportScatters& scatters, const std::string& label) {
  const KindReport section = kind_report(text_of(member(d, "kind")));
  return values.is_object() && section != nullptr ? section(values, index, histograms, scatters, label) : "";
}

std::string measurement_section(const json& d, const json& m, std::size_t index, const ReportHistograms& histograms,
                                const ReportScatters& scatters, bool rejected) {
  const std::string label = text_of(member(m, "measurement"));
  std::string out = fmt::format("<section class=\"measurement\" id=\"m{}\">\n<h3>[{}] {}</h3>\n", index, index, esc(label));
  out += decision_list(d);
  const bool ran = member(m, "ran").get<bool>();
  out += fmt::format("<p>Target {} ({}); achieved <b>{}</b>: {}{}{}.</p>\n", report_number(member(m, "target")),
                     esc(text_of(member(m, "error_measure"))), ran ? report_number(member(m, "achieved")) : "-",
                     met_text(ran, member(m, "met").get<bool>()),
                     member(m, "partial").get<bool>() ? " (partial: interrupted)" : "",
                     rejected ? R"(; its test <span class="notmet">rejected</span>)" : "");
  if (!ran) return out + "</section>\n";
  out += rounds_table(m);
  return out + measurement_values(d, member(m, "values"), index, histograms, scatters, label) + "</section>\n";
}

std::string measurements_sections(const json& doc, const ReportHistograms& histograms, const ReportScatters& scatters) {
  const json& decisions = member(member(doc, "plan"), "decisions");
  const json& measurements = member(member(doc, "results"), "measurements");
  std::string out = kind_summary_sections(doc, true) + "<h2>Measurements</h2>\n";
  for (std::size_t i = 0; i < measurements.size() && i < decisions.size(); ++i)
    out += measurement_section(decisions[i], measurements[i], i, histograms, scatters,
                               is_rejected(doc, member(measurements[i], "measurement")));
  for (std::size_t i = measurements.size(); i < decisions.size(); ++i)
    out += fmt::format("<section class=\"measurement\"><h3>[{}] {}</h3><p>Not reached (the run was interrupted "
                       "before it).</p></section>\n", i, esc(text_of(member(decisions[i], "measurement"))));
  return out;
}

}  // namespace

std::string report_number(double value) { return std::isfinite(value) ? fmt::format("{:.6g}", value) : "-"; }

std::string report_number(const nlohmann::json& value) {
  if (value.is_number_unsigned()) return std::to_string(value.get<std::uint64_t>());
  if (value.is_number_integer()) return std::to_string(value.get<std::int64_t>());
  return value.is_number() ? report_number(value.get<double>()) : "-";
}

std::string experiment_report_html(const nlohmann::json& document, const ReportHistograms& histograms,
                                   const ReportScatters& scatters) {
  std::string page = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  page += fmt::format("<title>microsim experiment {}</title>\n", esc(text_of(member(member(document, "spec"), "name"))));
  page += kStyle;
  page += "</head>\n<body>\n";
  page += verdict_headline(document) + status_section(document) + plan_section(document) + results_section(document);
  page += measurements_sections(document, histograms, scatters) + kind_summary_sections(document, false);
  page += "<h2>Files</h2>\n<p><a href=\"results.json\">results.json</a>: everything on this page as data.</p>\n";
  page += "<h2>The spec (canonical)</h2>\n<pre>" +
          esc(member(member(document, "spec"), "canonical").dump(2)) + "</pre>\n";
  return page + "</body>\n</html>\n";
}

namespace html {

std::string histogram_figure(const TracedHistogram& h, const std::string& label, const std::string& expected) {
  std::vector<BinnedComparison> comparisons;
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    if (k >= h.probability.size() || h.probability[k].size() != std::size_t(h.binnings[k].size())) continue;
    BinnedComparison c{h.binnings[k], std::vector<double>(h.counts[k].begin(), h.counts[k].end()), h.probability[k],
                       expected};
    for (double& e : c.expected) e *= double(h.hits);
    comparisons.push_back(std::move(c));
  }
  if (comparisons.empty()) return "";
  const std::string subtitle = fmt::format("{} counted of {}{}", h.hits, h.rays, h.partial ? " (PARTIAL)" : "");
  return "<figure>" + histogram_figure_svg(label, subtitle, comparisons) + "</figure>\n";
}

std::string estimate_text(const json& e) {
  return report_number(member(e, "value")) + " &plusmn; " + report_number(member(e, "standard_error"));
}

}  // namespace html

}  // namespace microsim::experiment
