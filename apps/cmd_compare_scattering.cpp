// microsim compare-scattering A.exr B.exr [C.exr]: two or three scattering results side by side, order by
// order (stats/scatter_compare.h): explicit surfaces, the Smith random walk, the analytic single scattering
// (a file of `microsim scatter --model analytic`, or --analytic: computed for the configuration the first
// file's notes record). Per pair, channel and order (1, 2, 3, 4, 5+ and the total; an expectation has order 1
// only): the total-variation distance of the shapes with its noise floor, the albedo difference with its
// standard error and p-value, and the weighted chi-square homogeneity test of the shapes (Gagunashvili 2010,
// "Chi-square tests for comparing weighted histograms", NIM A 614, 287). The verdict holds every test at the
// family-wise level --level (Sidak). Too little data for a test is an error, never a pass.
//
// Two or three files of `microsim trace vndf` (traced direction histograms) are compared binning by binning
// instead (compare_traced.h): the visible normals of two assemblies of one NDF, say.
//
// Exit codes: 0 every test passed, 1 a test rejected, 2 bad usage or input, or too little data (nothing
// written), 130 interrupted during --analytic (nothing written).
#include "command.h"
#include "compare_traced.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "core/ndf_kind.h"
#include "core/strict_parse.h"
#include "microfacet/material.h"
#include "microfacet/roughness.h"
#include "microgeom/exr_io.h"
#include "scatter/analytic_scatter.h"
#include "stats/scatter_compare.h"
#include "stats/scatter_figure.h"

#include <fmt/core.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct CompareArgs {
  std::vector<std::string> files;
  bool analytic = false;
  std::string json, svg, orders;  // empty: every order (scatter files)
  double level = 0.01;
  int threads = 0;
};

// One input: its file (or "analytic"), label (A, B, C) and content.
struct Input {
  std::string name, label;
  ScatterFile file;
};

std::vector<int> parse_orders(const std::string& text) {
  std::vector<int> orders;
  for (const std::string_view field : reader::split_commas(text)) {
    int k = -2;
    if (field == "total") k = kTotalOrder;
    else if (field == "5+") k = 4;
    else if (field.size() == 1 && field[0] >= '1' && field[0] <= '4') k = field[0] - '1';
    if (k == -2)
      throw UsageError(fmt::format("--orders {}: unknown order {} (1, 2, 3, 4, 5+ or total)", quote_excerpt(text),
                                   quote_excerpt(field)));
    if (std::find(orders.begin(), orders.end(), k) != orders.end())
      throw UsageError(fmt::format("--orders {}: order {} given twice", quote_excerpt(text), quote_excerpt(field)));
    orders.push_back(k);
  }
  return orders;
}

// A file of `microsim scatter` or `microsim trace vndf`, told apart by its format attribute.
struct AnyInput {
  std::optional<ScatterFile> scatter;
  std::optional<TracedHistogram> traced;
};

AnyInput read_any_input(const std::string& path) {
  if (!std::filesystem::exists(path)) throw UsageError(fmt::format("'{}': no such file", path));
  try {
    const microgeom::ExrImage image = microgeom::read_exr(path);
    if (is_traced_histogram_image(image)) return {std::nullopt, histogram_from_exr(image, path)};
    return {scatter_from_exr(image, path), std::nullopt};
  } catch (const std::runtime_error& e) {  // not an EXR, not a microsim file, a malformed one: bad input
    throw UsageError(e.what());
  }
}

ScatterFile read_input(const std::string& path) {
  AnyInput in = read_any_input(path);
  if (!in.scatter)
    throw UsageError(fmt::format("'{}' is a traced histogram (microsim trace vndf) among scatter files: compare files "
                                 "of one kind", path));
  return std::move(*in.scatter);
}

const std::string& note(const Input& in, const char* key) {
  const auto it = in.file.notes.find(key);
  if (it == in.file.notes.end())
    throw UsageError(fmt::format("--analytic: '{}' records no note.{} (files of `microsim scatter` do): give the "
                                 "analytic file of `microsim scatter --model analytic` instead", in.name, key));
  return it->second;
}

double note_number(const Input& in, const char* key) {
  const auto v = reader::parse_finite_double(note(in, key));
  if (!v) throw UsageError(fmt::format("--analytic: '{}' note.{} = {} is not a number", in.name, key, quote_excerpt(note(in, key))));
  return *v;
}

// The analytic single scattering of the configuration the first input's notes record, binned alike.
Input analytic_input(const Input& first, int threads) {
  const std::optional<NdfKind> ndf = ndf_kind_from_string(note(first, "ndf"));
  if (!ndf)
    throw UsageError(fmt::format("--analytic: '{}' note.ndf = {} (ggx or beckmann)", first.name,
                                 quote_excerpt(note(first, "ndf"))));
  const auto [ax, ay] = parse_alpha("--analytic note.alpha", note(first, "alpha"));
  const double theta = note_number(first, "theta") * kPi<double> / 180, phi = note_number(first, "phi") * kPi<double> / 180;
  const Material material = parse_material("--analytic note.material", note(first, "material"));
  const Vec3<double> wi(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
  const DirectionBinning b = DirectionBinning::from_description(nlohmann::json::parse(first.file.histogram.binning_id()));
  Input in{"analytic", "", {}};
  in.file.kind = ScatterFileKind::expectation;
  install_interrupt_handler();
  const RunControl run = cli_run_control(threads, nullptr);
  in.file.expectation = *ndf == NdfKind::beckmann
                            ? analytic_single_scattering(Beckmann<double>(ax, ay), wi, material, b.rows() / 2, run)
                            : analytic_single_scattering(GGX<double>(ax, ay), wi, material, b.rows() / 2, run);
  return in;
}

std::vector<Input> read_inputs(const CompareArgs& a) {
  std::vector<Input> inputs;
  for (const std::string& f : a.files) inputs.push_back({f, "", read_input(f)});
  if (a.analytic) {
    if (inputs.front().file.kind != ScatterFileKind::histogram)
      throw UsageError(fmt::format("--analytic: '{}' is already an expectation", inputs.front().name));
    inputs.push_back(analytic_input(inputs.front(), a.threads));
  }
  if (inputs.size() < 2 || inputs.size() > 3)
    throw UsageError(fmt::format("compare-scattering compares 2 or 3 results, got {} ({} files{})", inputs.size(),
                                 a.files.size(), a.analytic ? " and --analytic" : ""));
  for (std::size_t i = 0; i < inputs.size(); ++i) inputs[i].label = std::string(1, char('A' + i));
  return inputs;
}

struct PairComparison {
  std::size_t a = 0, b = 0;
  std::vector<LobeComparison> lobes;
};

std::vector<PairComparison> compare_pairs(const std::vector<Input>& in, const std::vector<int>& orders) {
  ScatterComparisonOptions options;
  options.order_bins = orders;
  std::vector<PairComparison> pairs;
  for (std::size_t i = 0; i < in.size(); ++i)
    for (std::size_t j = i + 1; j < in.size(); ++j) {
      try {
        pairs.push_back({i, j, compare_scatter_files(in[i].file, in[i].name, in[j].file, in[j].name, options)});
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
    }
  return pairs;
}

std::string channel_name(const ScatterFile& f, int c) {
  return f.kind == ScatterFileKind::histogram ? f.histogram.channel_name(c) : f.expectation.channel_names[std::size_t(c)];
}

// Too little data anywhere: an error naming every such comparison, never a pass.
void refuse_insufficient(const std::vector<Input>& in, const std::vector<PairComparison>& pairs) {
  std::string list;
  for (const PairComparison& p : pairs)
    for (const LobeComparison& l : p.lobes)
      if (!l.chi2)
        list += fmt::format("\n  {}-{} channel {} {}: {}", in[p.a].label, in[p.b].label, channel_name(in[p.a].file, l.channel),
                            scatter_order_name(l.order_bin), l.insufficient);
  if (!list.empty())
    throw UsageError("too little data to compare (leave these orders out with --orders, or measure more paths):" + list);
}

// The family: a chi-square and an albedo test per lobe comparison (comparison_family).
struct Verdict : ComparisonFamily {
  double level = 0;
};

Verdict verdict(const std::vector<PairComparison>& pairs, double level) {
  std::vector<const LobeComparison*> lobes;
  for (const PairComparison& p : pairs)
    for (const LobeComparison& l : p.lobes) lobes.push_back(&l);
  return {comparison_family(lobes, level), level};
}

nlohmann::json input_json(const Input& in) {
  nlohmann::json j{{"label", in.label}, {"file", in.name}};
  if (in.file.kind == ScatterFileKind::histogram) {
    j["kind"] = "histogram";
    j["producer"] = in.file.histogram.provenance.producer;
    j["measurement"] = in.file.histogram.provenance.measurement;
    j["paths"] = in.file.histogram.paths();
    j["partial"] = in.file.histogram.partial;
  } else {
    j["kind"] = "expectation";
    j["producer"] = in.file.expectation.producer;
    j["measurement"] = in.file.expectation.measurement;
  }
  j["notes"] = in.file.notes;
  return j;
}

nlohmann::json lobe_json(const LobeComparison& l, const std::string& channel, const Verdict& v) {
  nlohmann::json chi2 = to_json(*l.chi2);
  chi2["rejected"] = l.chi2->p_value < v.per_test;
  chi2["significance"] = v.per_test;
  return {{"channel", channel},
          {"order", scatter_order_name(l.order_bin)},
          {"tv", json_number(l.tv)},
          {"tv_noise_floor", json_number(l.tv_noise_floor)},
          {"albedo_a", json_estimate(l.albedo_a)},
          {"albedo_b", json_estimate(l.albedo_b)},
          {"albedo_difference", json_estimate(l.difference)},
          {"albedo_difference_p", l.difference_p},
          {"albedo_rejected", l.difference_p < v.per_test},
          {"chi2", chi2}};
}

nlohmann::json report_json(const std::vector<Input>& in, const std::vector<PairComparison>& pairs, const Verdict& v) {
  nlohmann::json j{{"level", v.level}, {"tests", v.tests}, {"per_test_significance", v.per_test}, {"rejected", v.rejected}};
  j["inputs"] = nlohmann::json::array();
  for (const Input& i : in) j["inputs"].push_back(input_json(i));
  j["comparisons"] = nlohmann::json::array();
  for (const PairComparison& p : pairs) {
    nlohmann::json lobes = nlohmann::json::array();
    for (const LobeComparison& l : p.lobes) lobes.push_back(lobe_json(l, channel_name(in[p.a].file, l.channel), v));
    j["comparisons"].push_back({{"a", in[p.a].label}, {"b", in[p.b].label}, {"lobes", lobes}});
  }
  return j;
}

void print_report(const std::vector<Input>& in, const std::vector<PairComparison>& pairs, const Verdict& v) {
  for (const Input& i : in) fmt::print("{} = {} ({})\n", i.label, i.name, input_json(i)["producer"].get<std::string>());
  fmt::print("{:<5} {:<8} {:<11} {:>22} {:>22} {:>22} {:>9} {:>9} {:>9}\n", "pair", "channel", "order", "albedo A",
             "albedo B", "A - B", "TV", "TV floor", "chi2 p");
  const auto e = [](const Estimate& x) { return fmt::format("{:.5f} +- {:.5f}", x.value, x.standard_error); };
  for (const PairComparison& p : pairs)
    for (const LobeComparison& l : p.lobes)
      fmt::print("{:<5} {:<8} {:<11} {:>22} {:>22} {:>22} {:>9.4f} {:>9.4f} {:>9.3g}\n", in[p.a].label + "-" + in[p.b].label,
                 channel_name(in[p.a].file, l.channel), scatter_order_name(l.order_bin), e(l.albedo_a), e(l.albedo_b),
                 e(l.difference), l.tv, l.tv_noise_floor, l.chi2->p_value);
  fmt::print("{}: {} tests at family-wise level {} (each at {:.3g}, Sidak)\n", v.rejected ? "REJECTED" : "passed", v.tests,
             v.level, v.per_test);
}

// The figure of channel 0: one row per order, the inputs' lobes and the pairs' shape residuals.
std::string figure(const std::vector<Input>& in, const std::vector<PairComparison>& pairs, const std::vector<int>& orders,
                   const Verdict& v) {
  std::vector<ScatterFigureRow> rows;
  for (int k : orders) {
    ScatterFigureRow row{scatter_order_name(k), {}, {}};
    for (const Input& i : in)
      if (const auto lobe = scatter_lobe(i.file, 0, k)) row.lobes.push_back({i.label + ": " + i.name, lobe->mean});
    for (const PairComparison& p : pairs) {
      const auto la = scatter_lobe(in[p.a].file, 0, k), lb = scatter_lobe(in[p.b].file, 0, k);
      if (la && lb) row.residuals.push_back({in[p.a].label + " - " + in[p.b].label, shape_residuals(*la, *lb, 10)});
    }
    if (!row.lobes.empty()) rows.push_back(std::move(row));
  }
  const DirectionBinning b = DirectionBinning::from_description(nlohmann::json::parse(
      in[0].file.kind == ScatterFileKind::histogram ? in[0].file.histogram.binning_id() : in[0].file.expectation.binning_id));
  std::string subtitle = fmt::format("channel {}; {}: {} tests, each at {:.3g}", channel_name(in[0].file, 0),
                                     v.rejected ? "REJECTED" : "passed", v.tests, v.per_test);
  for (const Input& i : in) subtitle += "\n" + i.label + " = " + i.name;
  return scatter_figure_svg("compare-scattering", subtitle, b, rows);
}

// A file given twice has nothing to compare with itself.
void refuse_repeated_files(const std::vector<std::string>& files) {
  for (std::size_t i = 0; i < files.size(); ++i)
    for (std::size_t j = i + 1; j < files.size(); ++j) {
      std::error_code ec;
      if (files[i] == files[j] || std::filesystem::equivalent(files[i], files[j], ec))
        throw UsageError(fmt::format("'{}' is given twice ({}): compare two different results", files[j], files[i]));
    }
}

// The inputs when the first file is a traced histogram (all must be, 2 or 3 of them), else nullopt.
std::optional<std::vector<TracedInput>> traced_inputs(const CompareArgs& a) {
  AnyInput first = read_any_input(a.files.front());
  if (!first.traced) return std::nullopt;
  if (a.analytic || !a.orders.empty())
    throw UsageError(fmt::format("{} applies to scatter files; '{}' is a traced histogram (microsim trace vndf: compare "
                                 "it with `microsim validate --against`, or with another traced histogram)",
                                 a.analytic ? "--analytic" : "--orders", a.files.front()));
  if (a.files.size() < 2 || a.files.size() > 3)
    throw UsageError(fmt::format("compare-scattering compares 2 or 3 traced histograms, got {} ('{}')", a.files.size(),
                                 fmt::join(a.files, "', '")));
  refuse_repeated_files(a.files);
  std::vector<TracedInput> inputs{{a.files.front(), std::move(*first.traced)}};
  for (std::size_t i = 1; i < a.files.size(); ++i) {
    AnyInput in = read_any_input(a.files[i]);
    if (!in.traced)
      throw UsageError(fmt::format("'{}' is a scatter file among traced histograms (microsim trace vndf): compare files "
                                   "of one kind", a.files[i]));
    inputs.push_back({a.files[i], std::move(*in.traced)});
  }
  return inputs;
}

int run_compare(const CompareArgs& a) {
  std::vector<PathOption> files;
  for (const std::string& f : a.files) files.push_back({"input", f});
  check_distinct_outputs(files, {{"--json", a.json}, {"--svg", a.svg}});
  if (!(a.level > 0 && a.level < 1)) throw UsageError(fmt::format("--level {}: must be in (0, 1)", a.level));
  if (!a.svg.empty() && std::filesystem::path(a.svg).extension() != ".svg")
    throw UsageError(fmt::format("--svg '{}': must be an .svg file", a.svg));
  check_output("--json", a.json);
  check_output("--svg", a.svg);
  if (const auto traced = traced_inputs(a)) return compare_traced_inputs(*traced, a.level, a.json, a.svg);
  const std::vector<int> orders = parse_orders(a.orders.empty() ? "1,2,3,4,5+,total" : a.orders);
  std::vector<Input> inputs;
  try {
    inputs = read_inputs(a);
  } catch (const Cancelled&) {
    return interrupted_nothing_written("compare-scattering", "during --analytic");
  }
  const std::vector<PairComparison> pairs = compare_pairs(inputs, orders);
  refuse_insufficient(inputs, pairs);
  const Verdict v = verdict(pairs, a.level);
  if (!a.json.empty()) write_file_atomically(a.json, report_json(inputs, pairs, v).dump(2) + "\n");
  if (!a.svg.empty()) write_file_atomically(a.svg, figure(inputs, pairs, orders, v));
  print_report(inputs, pairs, v);
  return v.rejected ? kExitRejected : kExitOk;
}

CommandRegistration compare_scattering_registration{"compare-scattering", [](CLI::App& app) {
  auto args = std::make_shared<CompareArgs>();
  auto* sub = app.add_subcommand(
      "compare-scattering",
      "Compare two or three scattering results (scatter EXR files: explicit surface, Smith walk, analytic single "
      "scattering) order by order: total-variation distance of the shapes, albedo difference with its error, and the "
      "weighted chi-square homogeneity test (Gagunashvili 2010). Two or three traced histograms of `microsim trace vndf` "
      "(two assemblies of one NDF, say) are compared binning by binning the same way (the fraction of rays that hit in "
      "place of the albedo). Exit 0 passed, 1 rejected, 2 bad input or too little data (nothing written).");
  sub->add_option("files", args->files,
                  "scatter EXR files (2 or 3; 1 or 2 with --analytic), or 2 or 3 traced histograms (trace vndf --out)")
      ->required();
  sub->add_flag("--analytic", args->analytic,
                "add the analytic single scattering of the first file's configuration (its notes: ndf, alpha, theta, "
                "phi, material)");
  sub->add_option("--orders", args->orders, "scatter files: orders to compare, a list of 1, 2, 3, 4, 5+, total")
      ->default_str("1,2,3,4,5+,total");
  add_number_option(sub, "--level", args->level, real(), "family-wise significance level of the verdict")->default_str("0.01");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("threads of the --analytic cubature (0: all cores)", kMaxThreads))
      ->default_str("0");
  sub->add_option("--json", args->json, "write the comparison as JSON");
  sub->add_option("--svg", args->svg, "write the figure (per-order lobes side by side, shape residual maps)");
  on_selected(sub, [args] { return run_compare(*args); });
}};

}  // namespace
}  // namespace microsim::app
