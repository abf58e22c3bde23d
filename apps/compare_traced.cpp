// compare-scattering's table and figures (compare_traced.h).
#include "compare_traced.h"

#include "stats/binning.h"
#include "stats/scatter_figure.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

namespace microsim::app {
namespace {

std::string traced_attr(const TracedHistogram& h, const char* key) {
  const auto it = h.attributes.find(key);
  return it == h.attributes.end() ? "?" : it->second;
}

std::string compared_channel(const ScatterFile& f, int c) {
  return f.kind == ScatterFileKind::histogram ? f.histogram.channel_name(c) : f.expectation.channel_names[std::size_t(c)];
}

std::string producer_of(const ScatterFile& f) {
  return f.kind == ScatterFileKind::histogram ? f.histogram.provenance.producer : f.expectation.producer;
}

void print_family_line(const ComparisonFamily& f, double level) {
  fmt::print("{}: {} tests at family-wise level {} (each at {:.3g}, Sidak)\n", f.rejected ? "REJECTED" : "passed",
             f.tests, level, f.per_test);
}

std::string verdict_subtitle(const ComparisonFamily& f) {
  return fmt::format("{}: {} tests, each at {:.3g}", f.rejected ? "REJECTED" : "passed", f.tests, f.per_test);
}

BinningKind traced_kind_of(const std::string& binning) {
  return binning == "sphere" ? BinningKind::sphere : BinningKind::lobe;
}

ScatterLobe traced_lobe_of(const TracedInput& in, const std::string& binning) {
  return traced_lobe(in.histogram, in.histogram.find(traced_kind_of(binning)));
}

// Whether every input has this binning as the first input has it (a figure row draws them all).
bool shared_by_all(const std::vector<TracedInput>& in, const std::string& binning) {
  const TracedHistogram& first = in.front().histogram;
  const DirectionBinning& b = first.binnings[std::size_t(first.find(traced_kind_of(binning)))];
  for (const TracedInput& i : in) {
    const int k = i.histogram.find(traced_kind_of(binning));
    if (k < 0 || i.histogram.binnings[std::size_t(k)].describe() != b.describe()) return false;
  }
  return true;
}

}  // namespace

void print_scatter_comparison(const ScatterComparison& c) {
  const std::vector<ScatterInput>& in = c.inputs;
  for (const ScatterInput& i : in) fmt::print("{} = {} ({})\n", i.label, i.name, producer_of(i.file));
  fmt::print("{:<5} {:<8} {:<11} {:>22} {:>22} {:>22} {:>9} {:>9} {:>9}\n", "pair", "channel", "order", "albedo A",
             "albedo B", "A - B", "TV", "TV floor", "chi2 p");
  const auto e = [](const Estimate& x) { return fmt::format("{:.5f} +- {:.5f}", x.value, x.standard_error); };
  for (const auto& p : c.pairs)
    for (const LobeComparison& l : p.comparisons)
      fmt::print("{:<5} {:<8} {:<11} {:>22} {:>22} {:>22} {:>9.4f} {:>9.4f} {:>9.3g}\n", in[p.a].label + "-" + in[p.b].label,
                 compared_channel(in[p.a].file, l.channel), scatter_order_name(l.order_bin), e(l.albedo_a),
                 e(l.albedo_b), e(l.difference), l.tv, l.tv_noise_floor, l.chi2->p_value);
  print_family_line(c.family, c.level);
}

void print_traced_comparison(const TracedComparisonSet& c) {
  for (const TracedInput& i : c.inputs)
    fmt::print("{} = {} (traced {}, alpha {}, theta {} deg, {} rays)\n", i.label, i.name,
               traced_attr(i.histogram, "surface"), traced_attr(i.histogram, "alpha"), traced_attr(i.histogram, "theta"),
               i.histogram.rays);
  fmt::print("{:<5} {:<8} {:>9} {:>9} {:>9} {:>12}\n", "pair", "binning", "TV", "TV floor", "chi2 p", "hits A - B p");
  for (const auto& p : c.pairs)
    for (const TracedComparison& t : p.comparisons)
      fmt::print("{:<5} {:<8} {:>9.4f} {:>9.4f} {:>9.3g} {:>12.3g}\n", c.inputs[p.a].label + "-" + c.inputs[p.b].label,
                 t.binning, t.lobe.tv, t.lobe.tv_noise_floor, t.lobe.chi2->p_value, t.lobe.difference_p);
  print_family_line(c.family, c.level);
  if (!c.note.empty()) fmt::print("note: {}\n", c.note);
}

std::string scatter_comparison_figure(const ScatterComparison& c) {
  const std::vector<ScatterInput>& in = c.inputs;
  std::vector<ScatterFigureRow> rows;
  for (int k : c.orders) {
    ScatterFigureRow row{scatter_order_name(k), {}, {}};
    for (const ScatterInput& i : in)
      if (const auto lobe = scatter_lobe(i.file, 0, k)) row.lobes.push_back({i.label + ": " + i.name, lobe->mean});
    for (const auto& p : c.pairs) {
      const auto la = scatter_lobe(in[p.a].file, 0, k), lb = scatter_lobe(in[p.b].file, 0, k);
      if (la && lb) row.residuals.push_back({in[p.a].label + " - " + in[p.b].label, shape_residuals(*la, *lb, 10)});
    }
    if (!row.lobes.empty()) rows.push_back(std::move(row));
  }
  const ScatterFile& f0 = in[0].file;
  const DirectionBinning b = DirectionBinning::from_description(nlohmann::json::parse(
      f0.kind == ScatterFileKind::histogram ? f0.histogram.binning_id() : f0.expectation.binning_id));
  std::string subtitle = fmt::format("channel {}; {}", compared_channel(f0, 0), verdict_subtitle(c.family));
  for (const ScatterInput& i : in) subtitle += "\n" + i.label + " = " + i.name;
  return scatter_figure_svg("compare-scattering", subtitle, b, rows);
}

std::string traced_comparison_figure(const TracedComparisonSet& c) {
  const std::vector<TracedInput>& in = c.inputs;
  std::vector<ScatterFigureRow> rows;
  for (const TracedComparison& t : c.pairs.front().comparisons) {
    if (!shared_by_all(in, t.binning)) continue;
    ScatterFigureRow row{t.binning + " binning", {}, {}};
    for (const TracedInput& i : in) row.lobes.push_back({i.label + ": " + i.name, traced_lobe_of(i, t.binning).mean});
    for (const auto& p : c.pairs)
      row.residuals.push_back({in[p.a].label + " - " + in[p.b].label,
                               shape_residuals(traced_lobe_of(in[p.a], t.binning), traced_lobe_of(in[p.b], t.binning), 10)});
    rows.push_back(std::move(row));
  }
  std::string subtitle = verdict_subtitle(c.family);
  for (const TracedInput& i : in) subtitle += "\n" + i.label + " = " + i.name;
  return scatter_figure_svg("compare-scattering: traced histograms", subtitle, in[0].histogram.binnings.front(), rows);
}

}  // namespace microsim::app
