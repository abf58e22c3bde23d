// experiment: the report page of a run (report.h).
#include "experiment/report.h"

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

using nlohmann::json;

std::string esc(const std::string& s) { return svg::escape(s); }

std::string text_of(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number()) return report_number(v);
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  return v.is_null() ? "-" : v.dump();
}

// The member `key` of `j`, or std::invalid_argument naming it.
const json& member(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key))
    throw std::invalid_argument(fmt::format("experiment_report_html: the document has no '{}'", key));
  return j.at(key);
}

std::string row(const std::vector<std::string>& cells, const char* tag = "td") {
  std::string out = "<tr>";
  for (const std::string& c : cells) out += fmt::format("<{0}>{1}</{0}>", tag, c);
  return out + "</tr>\n";
}

// A table; an empty header: none.
std::string table(const std::vector<std::string>& header, const std::string& body) {
  std::vector<std::string> escaped;
  for (const std::string& h : header) escaped.push_back(esc(h));
  const std::string head = header.empty() ? "" : "<thead>" + row(escaped, "th") + "</thead>\n";
  return "<table>\n" + head + "<tbody>\n" + body + "</tbody></table>\n";
}

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
    out += "<p class=\"partial\">PARTIAL: the run was interrupted; running the same command again resumes it. "
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

// The rows of one albedo quantity: E(mu) +- error per alpha, then E_avg +- error.
std::string albedo_quantity_table(const json& values, const json& q) {
  std::vector<std::string> header{"alpha"};
  for (const json& mu : member(values, "mus")) header.push_back("mu " + report_number(mu));
  header.push_back("E_avg");
  std::string body;
  const json& alphas = member(values, "alphas");
  for (std::size_t a = 0; a < alphas.size(); ++a) {
    std::vector<std::string> cells{report_number(alphas[a])};
    for (std::size_t k = 0; k < member(q, "value")[a].size(); ++k)
      cells.push_back(report_number(q["value"][a][k]) + " &plusmn; " + report_number(member(q, "error")[a][k]));
    cells.push_back("<b>" + report_number(member(q, "average")[a]) + "</b> &plusmn; " +
                    report_number(member(q, "average_error")[a]));
    body += row(cells);
  }
  return table(header, body);
}

std::string albedo_quantity_figure(const json& values, const std::string& name, const json& q) {
  std::vector<Curve> curves;
  const json& alphas = member(values, "alphas");
  for (std::size_t a = 0; a < alphas.size(); ++a)
    curves.push_back({"alpha " + report_number(alphas[a]), member(values, "mus").get<std::vector<double>>(),
                      member(q, "value")[a].get<std::vector<double>>(), member(q, "error")[a].get<std::vector<double>>()});
  if (curves.empty()) return "";
  const std::string subtitle = fmt::format("{} ({}), error bars: {}", text_of(member(values, "model")),
                                           text_of(member(values, "material")), text_of(member(values, "error")));
  return "<figure>" + curve_figure_svg(name + "(mu) per alpha", subtitle, {"mu = cos theta_i", name}, curves) +
         "</figure>\n";
}

std::string albedo_values(const json& values) {
  std::string out = fmt::format("<p>{} {}, {} side; error: {}.</p>\n", esc(text_of(member(values, "model"))),
                                esc(text_of(member(values, "material"))), esc(text_of(member(values, "side"))),
                                esc(text_of(member(values, "error"))));
  for (const json& name : member(values, "quantity_names")) {
    const std::string n = name.get<std::string>();
    const json& q = member(member(values, "quantities"), n.c_str());
    out += fmt::format("<h4>{}</h4>\n", esc(n)) + albedo_quantity_table(values, q);
    if (n != "unfinished" && n != "lost") out += albedo_quantity_figure(values, n, q);
  }
  return out;
}

std::string vndf_fit_table(const json& values) {
  std::string body;
  for (const json& fit : member(member(values, "analysis"), "binnings")) {
    std::vector<std::string> cells{esc(text_of(member(fit, "binning")))};
    for (const char* key : {"total_variation", "noise_floor_tv"}) cells.push_back(report_number(member(fit, key)));
    const json& chi2 = fit.contains("chi2") ? fit["chi2"] : json::object();
    for (const char* key : {"statistic", "dof", "p_value"})
      cells.push_back(chi2.contains(key) ? report_number(chi2[key]) : "-");
    body += row(cells);
  }
  return table({"binning", "TV vs analytic D_v", "noise floor TV", "chi-square", "dof", "p"}, body);
}

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

std::string vndf_values(const json& values, const ReportHistograms& histograms, std::size_t index,
                        const std::string& label) {
  std::string out = fmt::format("<p>{} rays, {} hits (expected hit fraction {}); measured TV against the analytic "
                                "D_v {}, noise floor {}.</p>\n",
                                text_of(member(values, "rays")), text_of(member(values, "hits")),
                                report_number(member(values, "expected_hit_fraction")),
                                report_number(member(values, "total_variation")),
                                report_number(member(values, "noise_floor_tv")));
  out += vndf_fit_table(values);
  if (values.contains("heightfield")) {
    const json& f = values["heightfield"];
    out += fmt::format("<p>On the tile ({}): TV to Smith with the tile's own NDF {} (its masking, without the NDF's "
                       "bias); back-facing first hits {}, convex-edge grazes passed over {}, leaked {}, unresolved {}.</p>\n",
                       esc(text_of(member(f, "surface"))), report_number(member(f, "tv_own_ndf")),
                       text_of(member(f, "backfacing")), text_of(member(f, "edge_grazes")), text_of(member(f, "leaked")),
                       text_of(member(f, "unresolved")));
  }
  const auto h = histograms.find(index);
  if (h != histograms.end()) out += histogram_figure(h->second, label, "analytic D_v");
  return out + fmt::format("<p>Histogram: <a href=\"vndf-{0}.exr\">vndf-{0}.exr</a>.</p>\n", index);
}

std::string estimate_text(const json& e) {
  return report_number(member(e, "value")) + " &plusmn; " + report_number(member(e, "standard_error"));
}

// Lobes in the hemispheres binning of `rows` rows per hemisphere, as a figure of the page.
std::string lobes_figure(const std::string& label, const std::string& subtitle, int rows,
                         const std::vector<ScatterFigureRow>& figure_rows) {
  return "<figure>" + scatter_figure_svg(label, subtitle, DirectionBinning::hemispheres(rows), figure_rows) + "</figure>\n";
}

std::string scatter_figure(const ScatterHistogram& h, const std::string& label, int rows) {
  std::vector<ScatterFigureRow> figure_rows;
  const double n = double(std::max<std::uint64_t>(h.paths(), 1));
  for (int k = 0; k < kScatterOrderBins; ++k) {
    const Histogram& lobe = h.histogram(0, k);
    std::vector<double> values;
    for (std::size_t b = 0; b < lobe.size(); ++b) values.push_back(lobe.weight(b) / n);
    figure_rows.push_back({scatter_order_name(k), {{"Smith walk", values}}, {}});
  }
  const std::string subtitle = fmt::format("{} paths; weight per launched path per bin", h.paths());
  return lobes_figure(label, subtitle, rows, figure_rows);
}

std::string expectation_figure(const ScatterExpectation& lobe, const std::string& label, int rows) {
  const std::vector<ScatterFigureRow> figure_rows{{"order 1", {{"analytic", lobe.order1.at(0)}}, {}}};
  const std::string subtitle = "the single-scattering expectation by cubature; weight per launched path per bin";
  return lobes_figure(label, subtitle, rows, figure_rows);
}

std::string scattering_values(const json& values, const ReportScatters& scatters, std::size_t index,
                              const std::string& label) {
  const json& s = member(values, "scattering");
  std::string out = fmt::format("<p>{} paths; albedo {}, left on the surface at the cap {}.</p>\n",
                                text_of(member(s, "paths")), estimate_text(member(s, "albedo")),
                                estimate_text(member(s, "unfinished")));
  std::string body;
  for (const json& o : member(s, "orders"))
    body += row({esc(text_of(member(o, "order"))), estimate_text(member(o, "albedo")), estimate_text(member(o, "reflected")),
                 estimate_text(member(o, "transmitted")), report_number(member(o, "noise_floor_tv")),
                 member(o, "targeted").get<bool>() ? "yes" : "no (below the target's share)"});
  out += table({"order", "albedo", "reflected", "transmitted", "lobe TV noise floor", "targeted"}, body);
  const auto h = scatters.find(index);
  if (h != scatters.end() && h->second.kind == ScatterFileKind::histogram)
    out += scatter_figure(h->second.histogram, label, member(s, "rows_per_hemisphere").get<int>());
  return out + fmt::format("<p>Walk sums: <a href=\"scattering-{0}.exr\">scattering-{0}.exr</a>.</p>\n", index);
}

std::string analytic_scattering_values(const json& values, const ReportScatters& scatters, std::size_t index,
                                       const std::string& label) {
  const json& s = member(values, "analytic_scattering");
  std::string out = fmt::format("<p>Order 1 by cubature (no rays): albedo {}, reflected {}, transmitted {}; error "
                                "estimate {} ({} of the albedo).</p>\n",
                                report_number(member(member(s, "albedo"), "value")),
                                report_number(member(member(s, "reflected"), "value")),
                                report_number(member(member(s, "transmitted"), "value")),
                                report_number(member(s, "error_estimate")), report_number(member(s, "relative_error")));
  const auto h = scatters.find(index);
  if (h != scatters.end() && h->second.kind == ScatterFileKind::expectation)
    out += expectation_figure(h->second.expectation, label, member(s, "rows_per_hemisphere").get<int>());
  return out + fmt::format("<p>Lobe: <a href=\"scattering-{0}.exr\">scattering-{0}.exr</a>.</p>\n", index);
}

std::string validation_tests_table(const json& v) {
  std::string body;
  for (const auto& [name, t] : member(v, "tests").items()) {
    std::vector<std::string> cells{esc(name)};
    for (const char* key : {"statistic", "dof", "p_value"}) cells.push_back(t.contains(key) ? report_number(t[key]) : "-");
    if (t.contains("rejected")) cells.push_back(text_of(t["rejected"]));
    else cells.push_back(t.contains("passed") ? (t["passed"].get<bool>() ? "no" : "yes") : "-");
    body += row(cells);
  }
  return table({"test", "statistic", "dof", "p", "rejected"}, body);
}

std::string validation_values(const json& values, const ReportHistograms& histograms, std::size_t index,
                              const std::string& label) {
  const json& v = member(values, "validation");
  std::string out = fmt::format("<p>Sampler <b>{}</b>, {} samples: verdict <b>{}</b> (p {}, level {}).</p>\n",
                                esc(text_of(member(v, "sampler"))), text_of(member(v, "samples")),
                                esc(text_of(member(v, "verdict"))), report_number(member(v, "p_value")),
                                report_number(member(v, "significance")));
  for (const json& f : member(v, "failures")) out += "<p class=\"notmet\">" + esc(text_of(f)) + "</p>\n";
  out += validation_tests_table(v);
  const auto h = histograms.find(index);
  if (h != histograms.end()) out += histogram_figure(h->second, label, "claimed pdf");
  return out + fmt::format("<p>Counts: <a href=\"validation-{0}.exr\">validation-{0}.exr</a>.</p>\n", index);
}

// ---- masking: values against Smith ---------------------------------------------------------------------

// A member's text, or "-" when absent.
std::string optional_number(const json& j, const char* key) { return j.contains(key) ? report_number(j[key]) : "-"; }

std::string difference_text(const json& j, const char* key) {
  return j.contains(key) ? estimate_text(j[key]) : "-";
}

// One row of a masking table: the value +- its standard error beside Smith's predictions and the differences.
std::vector<std::string> masking_row(const std::string& name, const json& v) {
  return {esc(name), estimate_text(v), optional_number(v, "smith_analytic"), optional_number(v, "smith_own_ndf"),
          difference_text(v, "difference"), difference_text(v, "difference_own_ndf")};
}

const std::vector<std::string> kMaskingHeader{"quantity", "value", "Smith (analytic NDF)", "Smith (own NDF)",
                                              "value - Smith (analytic)", "value - Smith (own NDF)"};

std::string light_text(const json& l) {
  return fmt::format("l = (theta {}, phi {})", report_number(member(l, "theta_deg")), report_number(member(l, "phi_deg")));
}

// Measured values with error bars against Smith's predictions (analytic NDF, own NDF) along x.
std::string masking_curves_figure(const std::string& title, const std::string& subtitle, const CurveAxes& axes,
                                  const std::vector<double>& x, const std::vector<const json*>& points) {
  Curve measured{"measured", x, {}, {}}, analytic{"Smith, analytic NDF", x, {}, {}}, own{"Smith, own NDF", x, {}, {}};
  for (const json* p : points) {
    measured.y.push_back(member(*p, "value").get<double>());
    measured.error.push_back(member(*p, "standard_error").get<double>());
    analytic.y.push_back(p->value("smith_analytic", std::nan("")));
    own.y.push_back(p->value("smith_own_ndf", std::nan("")));
  }
  const bool traced = std::any_of(own.y.begin(), own.y.end(), [](double y) { return std::isfinite(y); });
  if (!traced) analytic.label = "Smith's closed form (exact)";  // the analytic model: nothing measured
  std::vector<Curve> curves{analytic};
  if (traced) curves = {measured, analytic, own};
  return "<figure>" + curve_figure_svg(title, subtitle, axes, curves) + "</figure>\n";
}

std::string masking_bins_section(const json& bins, const std::string& what, const std::string& label) {
  std::string body;
  std::vector<double> x;
  std::vector<const json*> points;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    const json& b = bins[i];
    std::vector<std::string> cells = masking_row(fmt::format("bin {}: [{}, {}]", i, report_number(member(b, "lo")),
                                                             report_number(member(b, "hi"))), b);
    cells.insert(cells.begin() + 1, {report_number(member(b, "share")), text_of(member(b, "samples"))});
    body += row(cells);
    x.push_back(0.5 * (member(b, "lo").get<double>() + member(b, "hi").get<double>()));
    points.push_back(&b);
  }
  std::vector<std::string> header = kMaskingHeader;
  header[0] = "bin of " + what;
  header.insert(header.begin() + 1, {"share", "samples"});
  std::string out = fmt::format("<h4>G1(v | {})</h4>\n", esc(what)) + table(header, body);
  if (!points.empty())
    out += masking_curves_figure(label + ": G1(v | " + what + ")", "error bars: one standard error", {what, "G1(v | bin)"}, x, points);
  return out;
}

std::string masking_g2_figure(const json& g2, const std::string& label) {
  std::vector<double> x;
  std::vector<const json*> points;
  for (const json& g : g2) {
    x.push_back(member(member(g, "light"), "theta_deg").get<double>());
    points.push_back(&g);
  }
  if (points.size() < 2) return "";
  return masking_curves_figure(label + ": G2(v, l)", "against the light's theta (every light phi on one axis); error bars: one standard error",
                               {"theta_l (deg)", "G2(v, l)"}, x, points);
}

std::string masking_values(const json& values, const std::string& label) {
  const json& mk = member(values, "masking");
  const bool traced = text_of(member(mk, "model")) == "heightfield";
  std::string out = traced ? fmt::format("<p>Traced on {} (Smith's analytic NDF: {}): {} surface points, {} shadow rays; "
                                         "leak ratio {} (must be 1).</p>\n",
                                         esc(text_of(member(mk, "surface"))), esc(text_of(member(mk, "reference"))),
                                         text_of(member(mk, "samples")), text_of(member(mk, "rays")),
                                         estimate_text(member(mk, "leak_ratio")))
                           : fmt::format("<p>Smith's closed forms ({} NDF): Lambda(v) = {}; exact (standard error 0).</p>\n",
                                         esc(text_of(member(mk, "ndf"))), report_number(member(mk, "lambda")));
  std::string body;
  if (mk.contains("g1")) body += row(masking_row("G1(v)", mk["g1"]));
  if (mk.contains("g2"))
    for (const json& g : mk["g2"]) body += row(masking_row("G2(v, l), " + light_text(member(g, "light")), g));
  if (!body.empty()) out += table(kMaskingHeader, body);
  if (mk.contains("g2")) out += masking_g2_figure(mk["g2"], label);
  if (mk.contains("conditional")) {
    out += masking_bins_section(member(mk["conditional"], "by_normal"), "<v, m>", label);
    out += masking_bins_section(member(mk["conditional"], "by_height"), "height", label);
  }
  return out;
}

std::string measurement_values(const json& values, std::size_t index, const ReportHistograms& histograms,
                               const ReportScatters& scatters, const std::string& label) {
  if (!values.is_object()) return "";
  if (values.contains("quantity_names"))
    return albedo_values(values) + fmt::format("<p>Table: <a href=\"albedo-{0}.csv\">albedo-{0}.csv</a>.</p>\n", index);
  if (values.contains("analysis")) return vndf_values(values, histograms, index, label);
  if (values.contains("scattering")) return scattering_values(values, scatters, index, label);
  if (values.contains("analytic_scattering")) return analytic_scattering_values(values, scatters, index, label);
  if (values.contains("validation")) return validation_values(values, histograms, index, label);
  if (values.contains("masking")) return masking_values(values, label);
  return "";
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
  return out + measurement_values(member(m, "values"), index, histograms, scatters, label) + "</section>\n";
}

// G1(v) against theta_v per masking quantity, alpha and view phi (the masking curves against Smith), from
// the measurements that ran and measured G1; a curve needs two views.
std::string masking_curves_section(const json& decisions, const json& measurements) {
  std::map<std::string, std::pair<std::vector<double>, std::vector<const json*>>> curves;
  for (std::size_t i = 0; i < measurements.size() && i < decisions.size(); ++i) {
    const json& d = decisions[i];
    const json& values = member(measurements[i], "values");
    if (text_of(member(d, "kind")) != "masking" || !values.is_object() || !values.contains("masking") ||
        !values["masking"].contains("g1"))
      continue;
    const std::string key = fmt::format("{} alpha ({}, {}), phi_v {}", text_of(member(d, "quantity")),
                                        report_number(member(d, "alpha")[0]), report_number(member(d, "alpha")[1]),
                                        report_number(member(member(d, "view"), "phi_deg")));
    curves[key].first.push_back(member(member(d, "view"), "theta_deg").get<double>());
    curves[key].second.push_back(&values["masking"]["g1"]);
  }
  std::string out;
  for (const auto& [key, points] : curves)
    if (points.first.size() >= 2)
      out += masking_curves_figure("G1(v): " + key, "measured against Smith (analytic model: the closed form); error bars: one standard error",
                                   {"theta_v (deg)", "G1(v)"}, points.first, points.second);
  return out.empty() ? "" : "<h2>Masking curves</h2>\n" + out;
}

std::string measurements_sections(const json& doc, const ReportHistograms& histograms, const ReportScatters& scatters) {
  const json& decisions = member(member(doc, "plan"), "decisions");
  const json& measurements = member(member(doc, "results"), "measurements");
  std::string out = masking_curves_section(decisions, measurements) + "<h2>Measurements</h2>\n";
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

// Masking over several realisations (results.masking_realisations): per group, each value's mean, its standard
// error from the spread of the realisations and the Monte Carlo part alone.
std::string realisations_section(const json& document) {
  const json& results = member(document, "results");
  if (!results.contains("masking_realisations")) return "";
  std::string out = "<h2>Masking over realisations</h2>\n<p>Each value's mean over independent surfaces, its standard "
                    "error from their spread (surface-to-surface and Monte Carlo), and the Monte Carlo part alone.</p>\n";
  const auto value_row = [](const std::string& name, const json& v) {
    return row({esc(name), report_number(member(v, "mean")), report_number(member(v, "standard_error")),
                report_number(member(v, "monte_carlo_error"))});
  };
  for (const json& g : results["masking_realisations"]) {
    std::string body = value_row("G1", member(g, "g1"));
    if (g.contains("g2"))
      for (const json& v : g["g2"]) body += value_row("G2, light " + member(v, "light").dump(), v);
    if (g.contains("conditional"))
      for (const char* binning : {"by_normal", "by_height"})
        for (std::size_t b = 0; b < g["conditional"][binning].size(); ++b)
          body += value_row(fmt::format("G1 {} bin {}", binning, b + 1), g["conditional"][binning][b]);
    out += fmt::format("<h3>{} ({} realisations)</h3>\n", esc(text_of(member(g, "label"))), text_of(member(g, "realisations")));
    out += table({"value", "mean", "standard error (spread)", "Monte Carlo part"}, body);
  }
  return out;
}

std::string experiment_report_html(const nlohmann::json& document, const ReportHistograms& histograms,
                                   const ReportScatters& scatters) {
  std::string page = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  page += fmt::format("<title>microsim experiment {}</title>\n", esc(text_of(member(member(document, "spec"), "name"))));
  page += kStyle;
  page += "</head>\n<body>\n";
  page += verdict_headline(document) + status_section(document) + plan_section(document) + results_section(document);
  page += measurements_sections(document, histograms, scatters) + realisations_section(document);
  page += "<h2>Files</h2>\n<p><a href=\"results.json\">results.json</a>: everything on this page as data.</p>\n";
  page += "<h2>The spec (canonical)</h2>\n<pre>" +
          esc(member(member(document, "spec"), "canonical").dump(2)) + "</pre>\n";
  return page + "</body>\n</html>\n";
}

}  // namespace microsim::experiment
