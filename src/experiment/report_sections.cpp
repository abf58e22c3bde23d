// experiment: each kind's section of a measurement in the report (report_html.h).
#include "experiment/report_html.h"

#include "stats/curve_figure.h"
#include "stats/figure.h"
#include "stats/scatter_compare.h"
#include "stats/scatter_figure.h"

#include <algorithm>
#include <cmath>
#include <map>

namespace microsim::experiment {
namespace {

using namespace html;

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

}  // namespace

using namespace html;

std::string albedo_report(const json& values, std::size_t index, const ReportHistograms&, const ReportScatters&,
                          const std::string&) {
  if (!values.contains("quantity_names")) return "";
  return albedo_values(values) + fmt::format("<p>Table: <a href=\"albedo-{0}.csv\">albedo-{0}.csv</a>.</p>\n", index);
}

std::string vndf_report(const json& values, std::size_t index, const ReportHistograms& histograms, const ReportScatters&,
                        const std::string& label) {
  return values.contains("analysis") ? vndf_values(values, histograms, index, label) : "";
}

std::string scattering_report(const json& values, std::size_t index, const ReportHistograms&,
                              const ReportScatters& scatters, const std::string& label) {
  if (values.contains("scattering")) return scattering_values(values, scatters, index, label);
  if (values.contains("analytic_scattering")) return analytic_scattering_values(values, scatters, index, label);
  return "";
}

std::string validation_report(const json& values, std::size_t index, const ReportHistograms& histograms,
                              const ReportScatters&, const std::string& label) {
  return values.contains("validation") ? validation_values(values, histograms, index, label) : "";
}

std::string masking_report(const json& values, std::size_t, const ReportHistograms&, const ReportScatters&,
                           const std::string& label) {
  return values.contains("masking") ? masking_values(values, label) : "";
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

}  // namespace microsim::experiment
