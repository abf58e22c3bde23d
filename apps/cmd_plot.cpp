// `microsim plot HIST.exr --out FIG.svg`: the picture of a traced histogram (`microsim trace vndf`, on the
// ellipsoid or on a heightfield): observed counts, the expected counts stored with it (analytic D_v for the
// ellipsoid, Smith's D_v with the analytic NDF for a heightfield), and the Pearson residuals, per binning
// (src/microsim/figure.h).
#include "command.h"

#include "stats/figure.h"
#include "core/atomic_file.h"
#include "stats/histogram_io.h"
#include "core/parse.h"

#include <fmt/core.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace {

namespace fs = std::filesystem;
using microsim::app::UsageError;

struct PlotOptions {
  std::string histogram;
  std::string out;
};

std::string attribute(const microsim::TracedHistogram& h, const std::string& key) {
  const auto it = h.attributes.find(key);
  return it == h.attributes.end() ? std::string("?") : it->second;
}

// Comma-separated numbers of an attribute, printed with 6 significant digits (files store 17).
std::string short_numbers(const microsim::TracedHistogram& h, const std::string& key) {
  const std::string value = attribute(h, key);
  std::string out;
  std::size_t start = 0;
  while (start <= value.size()) {
    const std::size_t end = std::min(value.find(',', start), value.size());
    const std::string item = value.substr(start, end - start);
    const std::optional<double> x = microsim::try_parse_double(item);
    const std::string shown = x ? fmt::format("{:.6g}", *x)
                                : item.size() <= microsim::kExcerptBytes ? item : microsim::quote_excerpt(item);
    out += (out.empty() ? "" : ",") + shown;
    start = end + 1;
  }
  return out;
}

int run_plot(const PlotOptions& o) {
  using namespace microsim;
  microsim::app::check_distinct_outputs({{"histogram", o.histogram}}, {{"--out", o.out}});
  if (fs::path(o.out).extension() != ".svg")
    throw UsageError(fmt::format("--out: '{}' must end in .svg (the figure is SVG)", o.out));
  microsim::app::check_output("--out", o.out);
  TracedHistogram h;
  try {
    h = read_histogram_exr(o.histogram);
  } catch (const HistogramIoError& e) {
    throw UsageError(e.what());
  }
  std::vector<BinnedComparison> comparisons;
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    if (k >= h.probability.size() || h.probability[k].size() != std::size_t(h.binnings[k].size()))
      throw UsageError(fmt::format("'{}': the {} binning has no expected counts (channel {}.expected) to compare with",
                                   o.histogram, h.binnings[k].name(), h.binnings[k].name()));
    BinnedComparison c{h.binnings[k], std::vector<double>(h.counts[k].begin(), h.counts[k].end()), h.probability[k],
                       attribute(h, "surface") == "ellipsoid" ? "analytic D_v" : "Smith D_v (analytic NDF)"};
    for (double& e : c.expected) e *= double(h.hits);
    comparisons.push_back(std::move(c));
  }
  const std::string title = fmt::format("traced {} ({}): alpha {}, theta {} deg, phi {} deg", attribute(h, "surface"),
                                        attribute(h, "target"), short_numbers(h, "alpha"),
                                        short_numbers(h, "theta"), short_numbers(h, "phi"));
  const std::string subtitle = fmt::format("{}: {} rays, {} hits, seed {}{}", o.histogram, h.rays, h.hits,
                                           attribute(h, "seed"), h.partial ? " (PARTIAL: interrupted run)" : "");
  try {
    write_file_atomically(o.out, histogram_figure_svg(title, subtitle, comparisons));
  } catch (const FileWriteError& e) {
    throw UsageError(fmt::format("--out: {}", e.what()));
  }
  fmt::print("wrote {} ({} binnings)\n", o.out, comparisons.size());
  return microsim::app::kExitOk;
}

microsim::app::CommandRegistration plot_registration{"plot", [](CLI::App& app) {
  auto o = std::make_shared<PlotOptions>();
  auto* sub = app.add_subcommand(
      "plot",
      "Draw a traced histogram (from `microsim trace vndf --out HIST.exr`) as an SVG figure: per binning, the "
      "observed counts, the expected counts stored with it (analytic D_v; Smith's for a heightfield) and the "
      "Pearson residuals (observed - expected) / sqrt(expected). Exit 0 written, 2 bad input.");
  sub->add_option("histogram", o->histogram, "traced histogram EXR")->required();
  sub->add_option("--out", o->out, "the figure, FIG.svg (written atomically)")->required();
  microsim::app::on_selected(sub, [o] { return run_plot(*o); });
}};

}  // namespace
