// `microsim plot HIST.exr --out FIG.svg`: the picture of a traced histogram (`microsim trace vndf`, on the
// ellipsoid or on a heightfield): observed counts, the expected counts stored with it (analytic D_v for the
// ellipsoid, Smith's D_v with the analytic NDF for a heightfield), and the Pearson residuals, per binning
// (src/stats/figure.h); or of a scattering result (`microsim scatter --out F.exr`): its lobes by order
// (src/stats/scatter_figure.h).
#include "command.h"

#include "stats/figure.h"
#include "core/atomic_file.h"
#include "stats/histogram_io.h"
#include "stats/scatter_compare.h"
#include "stats/scatter_figure.h"
#include "stats/scatter_io.h"
#include "core/parse.h"
#include "measure/merge.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

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

// The figure of a scattering result (`microsim scatter --out F.exr`): one row per order (1-4, 5+, total; an
// expectation has order 1 only), each channel's lobe side by side, the mean weight per launched path in each
// bin of the hemispheres binning (stats/scatter_figure.h, as compare-scattering --svg draws lobes).
std::string scatter_figure(const std::string& path, const microsim::ScatterFile& f) {
  using namespace microsim;
  const bool measured = f.kind == ScatterFileKind::histogram;
  const int channels = measured ? f.histogram.channels() : f.expectation.channels();
  std::vector<ScatterFigureRow> rows;
  for (const int k : {0, 1, 2, 3, 4, kTotalOrder}) {
    ScatterFigureRow row{scatter_order_name(k), {}, {}};
    for (int c = 0; c < channels; ++c) {
      const std::string& name = measured ? f.histogram.channel_name(c) : f.expectation.channel_names[std::size_t(c)];
      if (const auto lobe = scatter_lobe(f, c, k)) row.lobes.push_back({"channel " + name, lobe->mean});
    }
    if (!row.lobes.empty()) rows.push_back(std::move(row));
  }
  std::string notes;
  for (const auto& [key, value] : f.notes) notes += (notes.empty() ? "" : ", ") + key + " " + value;
  const std::string subtitle =
      measured ? fmt::format("{}: {} paths, {}{}", path, f.histogram.paths(), f.histogram.provenance.producer,
                             f.histogram.partial ? " (PARTIAL: interrupted run)" : "")
               : fmt::format("{}: expectation, {}", path, f.expectation.producer);
  const DirectionBinning b = DirectionBinning::from_description(
      nlohmann::json::parse(measured ? f.histogram.binning_id() : f.expectation.binning_id));
  return scatter_figure_svg("scattering: weight per launched path by order", subtitle + "\n" + notes, b, rows);
}

// Reads the scatter EXR `path` and draws it.
std::string scatter_file_figure(const std::string& path) {
  try {
    return scatter_figure(path, microsim::read_scatter_exr(path));
  } catch (const microsim::ScatterIoError& e) {
    throw UsageError(e.what());
  }
}

void write_figure(const std::string& out, const std::string& svg) {
  try {
    microsim::write_file_atomically(out, svg);
  } catch (const microsim::FileWriteError& e) {
    throw UsageError(fmt::format("--out: {}", e.what()));
  }
}

int run_plot(const PlotOptions& o) {
  using namespace microsim;
  microsim::app::check_distinct_outputs({{"histogram", o.histogram}}, {{"--out", o.out}});
  if (fs::path(o.out).extension() != ".svg")
    throw UsageError(fmt::format("--out: '{}' must end in .svg (the figure is SVG)", o.out));
  microsim::app::check_output("--out", o.out);
  if (microsim::is_scatter_part(o.histogram)) {
    write_figure(o.out, scatter_file_figure(o.histogram));
    fmt::print("wrote {} (scattering lobes by order)\n", o.out);
    return microsim::app::kExitOk;
  }
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
  write_figure(o.out, histogram_figure_svg(title, subtitle, comparisons));
  fmt::print("wrote {} ({} binnings)\n", o.out, comparisons.size());
  return microsim::app::kExitOk;
}

microsim::app::CommandRegistration plot_registration{"plot", [](CLI::App& app) {
  auto o = std::make_shared<PlotOptions>();
  auto* sub = app.add_subcommand(
      "plot",
      "Draw a traced histogram (from `microsim trace vndf --out HIST.exr`) as an SVG figure: per binning, the "
      "observed counts, the expected counts stored with it (analytic D_v; Smith's for a heightfield) and the "
      "Pearson residuals (observed - expected) / sqrt(expected). A scattering result (`microsim scatter --out "
      "F.exr`) is drawn as its lobes by order and channel (to compare results: compare-scattering --svg). Exit 0 "
      "written, 2 bad input.");
  sub->add_option("histogram", o->histogram, "traced histogram EXR, or scatter EXR")->required();
  sub->add_option("--out", o->out, "the figure, FIG.svg (written atomically)")->required();
  microsim::app::on_selected(sub, [o] { return run_plot(*o); });
}};

}  // namespace
