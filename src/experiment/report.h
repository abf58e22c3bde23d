// experiment: the report of a run, DIR/index.html: one self-contained page, readable offline in
// any browser without JavaScript (inline CSS and SVG figures, no external resource), with
//   the status (complete or partial, every target met or not), the command, version, seed and spec digest
//   that reproduce it; the plan (every decision, its reason, the pilot and predicted time); the results
//   (target, achieved error, rounds, cost); and per measurement its values and figures:
//     albedo  the table of E(mu) +- error per alpha and E_avg, per quantity, and a chart of E(mu) per alpha
//             (stats/curve_figure.h);
//     vndf    the fit against the analytic D_v per binning (TV, noise floor, chi-square) and the figure of
//             observed, expected and residual counts (stats/figure.h, as `microsim plot` draws it);
//     scattering  per order the albedo (reflected, transmitted) and the lobe's TV noise floor, and the lobes
//             per order (stats/scatter_figure.h, as `microsim compare-scattering` draws them); analytic: the
//             order-1 albedo, the cubature's error estimate and the lobe;
//     validation  the verdict, every test, and the figure of the counts against the claimed pdf.
// The page is built from the run's document (results.json, run_directory.h) and the VNDF histograms (the
// counts behind the figures, which results.json does not hold). Numbers are printed by report_number.
// Pure: returns the text; run_directory.h writes it.
#pragma once

#include "stats/histogram_io.h"
#include "stats/scatter_io.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <map>
#include <string>

namespace microsim::experiment {

// VNDF histograms (with their analytic probabilities) by measurement index.
using ReportHistograms = std::map<std::size_t, TracedHistogram>;
// Scattering measurements' summed walks (the per-order lobes) or analytic order-1 lobes, by measurement index.
using ReportScatters = std::map<std::size_t, ScatterFile>;

// The page. Throws std::invalid_argument when the document lacks a member the page needs (a document
// not written by run_document).
std::string experiment_report_html(const nlohmann::json& document, const ReportHistograms& histograms,
                                   const ReportScatters& scatters = {});

// How the page prints a measured number: 6 significant digits ("{:.6g}"), "-" for a non-number.
std::string report_number(const nlohmann::json& value);
std::string report_number(double value);

}  // namespace microsim::experiment
