// compare-scattering on traced direction histograms (compare_traced.h).
#include "compare_traced.h"

#include "command.h"

#include "core/atomic_file.h"
#include "stats/chi2.h"
#include "stats/histogram_compare.h"
#include "stats/scatter_figure.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>

namespace microsim::app {

nlohmann::json json_number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
nlohmann::json json_estimate(const Estimate& e) { return {{"value", e.value}, {"standard_error", e.standard_error}}; }

namespace {

struct Pair {
  std::size_t a = 0, b = 0;
  std::vector<TracedComparison> binnings;
};

std::string label(std::size_t i) { return std::string(1, char('A' + i)); }

std::vector<Pair> compare_pairs(const std::vector<TracedInput>& in) {
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < in.size(); ++i)
    for (std::size_t j = i + 1; j < in.size(); ++j) try {
        pairs.push_back({i, j, compare_traced_histograms(in[i].histogram, in[i].name, in[j].histogram, in[j].name,
                                                         effective_entry_options())});
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
  std::string list;
  for (const Pair& p : pairs)
    for (const TracedComparison& c : p.binnings)
      if (!c.lobe.chi2) list += fmt::format("\n  {}-{} {} binning: {}", label(p.a), label(p.b), c.binning, c.lobe.insufficient);
  if (!list.empty()) throw UsageError("too little data to compare (trace more rays, or fewer --rows):" + list);
  return pairs;
}

// The family: a chi-square test of the shapes and a test of the hit fractions per comparison (Sidak).
using Family = ComparisonFamily;

Family family(const std::vector<Pair>& pairs, double level) {
  std::vector<const LobeComparison*> lobes;
  for (const Pair& p : pairs)
    for (const TracedComparison& c : p.binnings) lobes.push_back(&c.lobe);
  return comparison_family(lobes, level);
}

nlohmann::json comparison_json(const TracedComparison& c, const Family& f) {
  nlohmann::json chi2 = to_json(*c.lobe.chi2);
  chi2["rejected"] = c.lobe.chi2->p_value < f.per_test;
  chi2["significance"] = f.per_test;
  return {{"binning", c.binning},         {"tv", json_number(c.lobe.tv)},
          {"tv_noise_floor", json_number(c.lobe.tv_noise_floor)},
          {"hit_fraction_a", json_estimate(c.lobe.albedo_a)}, {"hit_fraction_b", json_estimate(c.lobe.albedo_b)},
          {"hit_fraction_difference_p", c.lobe.difference_p}, {"hit_fraction_rejected", c.lobe.difference_p < f.per_test},
          {"chi2", chi2}};
}

std::string attribute(const TracedHistogram& h, const char* key) {
  const auto it = h.attributes.find(key);
  return it == h.attributes.end() ? "?" : it->second;
}

// Traced tiles (not the exact ellipsoid) hold finite sets of facets: two tiles of one assembly differ by more
// than the rays' noise the floor and the tests count.
std::string tile_note(const std::vector<TracedInput>& in) {
  for (const TracedInput& i : in)
    if (attribute(i.histogram, "surface") != "ellipsoid")
      return "the noise floor and the tests count the rays' noise only: tiles of one assembly built from other seeds "
             "also differ by their finite sets of facets (`surface build` reports that noise: 'noise of N independent "
             "triangles'); compare tiles of one seed, or tiles large enough that their facets' noise is below the rays'";
  return "";
}

nlohmann::json report_json(const std::vector<TracedInput>& in, const std::vector<Pair>& pairs, const Family& f, double level) {
  nlohmann::json j{{"kind", "traced-histograms"}, {"level", level}, {"tests", f.tests},
                   {"per_test_significance", f.per_test}, {"rejected", f.rejected}};
  j["inputs"] = nlohmann::json::array();
  for (std::size_t i = 0; i < in.size(); ++i)
    j["inputs"].push_back({{"label", label(i)}, {"file", in[i].name}, {"rays", in[i].histogram.rays},
                           {"hits", in[i].histogram.hits}, {"partial", in[i].histogram.partial},
                           {"attributes", in[i].histogram.attributes}});
  j["notes"] = nlohmann::json::array();
  if (const std::string note = tile_note(in); !note.empty()) j["notes"].push_back(note);
  j["comparisons"] = nlohmann::json::array();
  for (const Pair& p : pairs) {
    nlohmann::json binnings = nlohmann::json::array();
    for (const TracedComparison& c : p.binnings) binnings.push_back(comparison_json(c, f));
    j["comparisons"].push_back({{"a", label(p.a)}, {"b", label(p.b)}, {"binnings", binnings}});
  }
  return j;
}

void print_report(const std::vector<TracedInput>& in, const std::vector<Pair>& pairs, const Family& f, double level) {
  for (std::size_t i = 0; i < in.size(); ++i)
    fmt::print("{} = {} (traced {}, alpha {}, theta {} deg, {} rays)\n", label(i), in[i].name,
               attribute(in[i].histogram, "surface"), attribute(in[i].histogram, "alpha"),
               attribute(in[i].histogram, "theta"), in[i].histogram.rays);
  fmt::print("{:<5} {:<8} {:>9} {:>9} {:>9} {:>12}\n", "pair", "binning", "TV", "TV floor", "chi2 p", "hits A - B p");
  for (const Pair& p : pairs)
    for (const TracedComparison& c : p.binnings)
      fmt::print("{:<5} {:<8} {:>9.4f} {:>9.4f} {:>9.3g} {:>12.3g}\n", label(p.a) + "-" + label(p.b), c.binning, c.lobe.tv,
                 c.lobe.tv_noise_floor, c.lobe.chi2->p_value, c.lobe.difference_p);
  fmt::print("{}: {} tests at family-wise level {} (each at {:.3g}, Sidak)\n", f.rejected ? "REJECTED" : "passed", f.tests,
             level, f.per_test);
  if (const std::string note = tile_note(in); !note.empty()) fmt::print("note: {}\n", note);
}

BinningKind kind_of(const std::string& binning) { return binning == "sphere" ? BinningKind::sphere : BinningKind::lobe; }

ScatterLobe lobe_of(const TracedInput& in, const std::string& binning) {
  return traced_lobe(in.histogram, in.histogram.find(kind_of(binning)));
}

// Whether every input has this binning as the first input has it (a figure row draws them all).
bool shared_by_all(const std::vector<TracedInput>& in, const std::string& binning) {
  const TracedHistogram& first = in.front().histogram;
  const DirectionBinning& b = first.binnings[std::size_t(first.find(kind_of(binning)))];
  for (const TracedInput& i : in) {
    const int k = i.histogram.find(kind_of(binning));
    if (k < 0 || i.histogram.binnings[std::size_t(k)].describe() != b.describe()) return false;
  }
  return true;
}

// One row per binning the first pair shares: the inputs' histograms and every pair's shape residuals.
std::string figure(const std::vector<TracedInput>& in, const std::vector<Pair>& pairs, const Family& f) {
  std::vector<ScatterFigureRow> rows;
  for (const TracedComparison& c : pairs.front().binnings) {
    if (!shared_by_all(in, c.binning)) continue;
    ScatterFigureRow row{c.binning + " binning", {}, {}};
    for (std::size_t i = 0; i < in.size(); ++i) row.lobes.push_back({label(i) + ": " + in[i].name, lobe_of(in[i], c.binning).mean});
    for (const Pair& p : pairs)
      row.residuals.push_back({label(p.a) + " - " + label(p.b),
                               shape_residuals(lobe_of(in[p.a], c.binning), lobe_of(in[p.b], c.binning), 10)});
    rows.push_back(std::move(row));
  }
  std::string subtitle = fmt::format("{}: {} tests, each at {:.3g}", f.rejected ? "REJECTED" : "passed", f.tests, f.per_test);
  for (std::size_t i = 0; i < in.size(); ++i) subtitle += "\n" + label(i) + " = " + in[i].name;
  return scatter_figure_svg("compare-scattering: traced histograms", subtitle, in[0].histogram.binnings.front(), rows);
}

}  // namespace

int compare_traced_inputs(const std::vector<TracedInput>& inputs, double level, const std::string& json,
                          const std::string& svg) {
  const std::vector<Pair> pairs = compare_pairs(inputs);
  const Family f = family(pairs, level);
  if (!json.empty()) write_file_atomically(json, report_json(inputs, pairs, f, level).dump(2) + "\n");
  if (!svg.empty()) write_file_atomically(svg, figure(inputs, pairs, f));
  print_report(inputs, pairs, f, level);
  return f.rejected ? kExitRejected : kExitOk;
}

}  // namespace microsim::app
