// measure: compare-scattering as a library call (compare_scattering.h).
#include "measure/compare_scattering.h"
#include "stats/json_values.h"

#include "core/errors.h"
#include "core/math.h"
#include "core/ndf_kind.h"
#include "core/strict_parse.h"
#include "microfacet/material.h"
#include "microfacet/roughness.h"
#include "microgeom/exr_io.h"
#include "scatter/analytic_scatter.h"
#include "stats/binning.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace microsim {
namespace {

using std::invalid_argument;

std::string input_label(std::size_t i) { return std::string(1, char('A' + i)); }


// A file of `microsim scatter` or of `microsim trace vndf`, told apart by its format attribute.
struct ComparedFile {
  std::optional<ScatterFile> scatter;
  std::optional<TracedHistogram> traced;
};

ComparedFile read_compared_file(const std::string& path) {
  if (!std::filesystem::exists(path)) throw invalid_argument(fmt::format("'{}': no such file", path));
  try {
    const microgeom::ExrImage image = microgeom::read_exr(path);
    if (is_traced_histogram_image(image)) return {std::nullopt, histogram_from_exr(image, path)};
    return {scatter_from_exr(image, path), std::nullopt};
  } catch (const std::runtime_error& e) {  // not an EXR, not a microsim file, a malformed one: bad input
    throw invalid_argument(e.what());
  }
}

// A file given twice has nothing to compare with itself.
void refuse_repeated_files(const std::vector<std::string>& files) {
  for (std::size_t i = 0; i < files.size(); ++i)
    for (std::size_t j = i + 1; j < files.size(); ++j) {
      std::error_code ec;
      if (files[i] == files[j] || std::filesystem::equivalent(files[i], files[j], ec))
        throw invalid_argument(fmt::format("'{}' is given twice ({}): compare two different results", files[j], files[i]));
    }
}

const std::string& scatter_note(const ScatterInput& in, const char* key) {
  const auto it = in.file.notes.find(key);
  if (it == in.file.notes.end())
    throw invalid_argument(fmt::format("--analytic: '{}' records no note.{} (files of `microsim scatter` do): give the "
                                       "analytic file of `microsim scatter --model analytic` instead", in.name, key));
  return it->second;
}

double scatter_note_number(const ScatterInput& in, const char* key) {
  const auto v = reader::parse_finite_double(scatter_note(in, key));
  if (!v)
    throw invalid_argument(fmt::format("--analytic: '{}' note.{} = {} is not a number", in.name, key,
                                       quote_excerpt(scatter_note(in, key))));
  return *v;
}

// The analytic single scattering of the configuration the first input's notes record, binned alike.
ScatterInput analytic_scatter_input(const ScatterInput& first, const RunControl& run) {
  const std::optional<NdfKind> ndf = ndf_kind_from_string(scatter_note(first, "ndf"));
  if (!ndf)
    throw invalid_argument(fmt::format("--analytic: '{}' note.ndf = {} (ggx or beckmann)", first.name,
                                       quote_excerpt(scatter_note(first, "ndf"))));
  const auto [ax, ay] = parse_alpha("--analytic note.alpha", scatter_note(first, "alpha"));
  const double theta = scatter_note_number(first, "theta") * kPi<double> / 180;
  const double phi = scatter_note_number(first, "phi") * kPi<double> / 180;
  const Material material = parse_material("--analytic note.material", scatter_note(first, "material"));
  const Vec3<double> wi(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
  const DirectionBinning b = DirectionBinning::from_description(nlohmann::json::parse(first.file.histogram.binning_id()));
  ScatterInput in{"analytic", "", {}};
  in.file.kind = ScatterFileKind::expectation;
  in.file.expectation = *ndf == NdfKind::beckmann
                            ? analytic_single_scattering(Beckmann<double>(ax, ay), wi, material, b.rows() / 2, run)
                            : analytic_single_scattering(GGX<double>(ax, ay), wi, material, b.rows() / 2, run);
  return in;
}

// The inputs when the first file (read already) is a scatter file.
std::vector<ScatterInput> scatter_inputs(const CompareScatteringRequest& r, ScatterFile first, const RunControl& run) {
  std::vector<ScatterInput> inputs{{r.files.front(), "", std::move(first)}};
  for (std::size_t i = 1; i < r.files.size(); ++i) {
    ComparedFile in = read_compared_file(r.files[i]);
    if (!in.scatter)
      throw invalid_argument(fmt::format("'{}' is a traced histogram (microsim trace vndf) among scatter files: compare "
                                         "files of one kind", r.files[i]));
    inputs.push_back({r.files[i], "", std::move(*in.scatter)});
  }
  if (r.analytic) {
    if (inputs.front().file.kind != ScatterFileKind::histogram)
      throw invalid_argument(fmt::format("--analytic: '{}' is already an expectation", inputs.front().name));
    inputs.push_back(analytic_scatter_input(inputs.front(), run));
  }
  if (inputs.size() < 2 || inputs.size() > 3)
    throw invalid_argument(fmt::format("compare-scattering compares 2 or 3 results, got {} ({} files{})", inputs.size(),
                                       r.files.size(), r.analytic ? " and --analytic" : ""));
  for (std::size_t i = 0; i < inputs.size(); ++i) inputs[i].label = input_label(i);
  return inputs;
}

std::string scatter_channel_name(const ScatterFile& f, int c) {
  return f.kind == ScatterFileKind::histogram ? f.histogram.channel_name(c) : f.expectation.channel_names[std::size_t(c)];
}

// Every pair's comparisons; too little data anywhere is an error naming every such comparison.
void compare_scatter_pairs(ScatterComparison& c) {
  ScatterComparisonOptions options;
  options.order_bins = c.orders;
  const std::vector<ScatterInput>& in = c.inputs;
  for (std::size_t i = 0; i < in.size(); ++i)
    for (std::size_t j = i + 1; j < in.size(); ++j)
      c.pairs.push_back({i, j, compare_scatter_files(in[i].file, in[i].name, in[j].file, in[j].name, options)});
  std::string list;
  std::vector<const LobeComparison*> lobes;
  for (const auto& p : c.pairs)
    for (const LobeComparison& l : p.comparisons) {
      lobes.push_back(&l);
      if (!l.chi2)
        list += fmt::format("\n  {}-{} channel {} {}: {}", in[p.a].label, in[p.b].label,
                            scatter_channel_name(in[p.a].file, l.channel), scatter_order_name(l.order_bin), l.insufficient);
    }
  if (!list.empty())
    throw invalid_argument("too little data to compare (leave these orders out with --orders, or measure more paths):" + list);
  c.family = comparison_family(lobes, c.level);
}

std::string traced_attribute(const TracedHistogram& h, const char* key) {
  const auto it = h.attributes.find(key);
  return it == h.attributes.end() ? "?" : it->second;
}

// Traced tiles (not the exact ellipsoid) hold finite sets of facets: two tiles of one assembly differ by more
// than the rays' noise the floor and the tests count.
std::string tile_note(const std::vector<TracedInput>& in) {
  for (const TracedInput& i : in)
    if (traced_attribute(i.histogram, "surface") != "ellipsoid")
      return "the noise floor and the tests count the rays' noise only: tiles of one assembly built from other seeds "
             "also differ by their finite sets of facets (`surface build` reports that noise: 'noise of N independent "
             "triangles'); compare tiles of one seed, or tiles large enough that their facets' noise is below the rays'";
  return "";
}

std::vector<TracedInput> traced_inputs(const CompareScatteringRequest& r, TracedHistogram first) {
  if (r.analytic || !r.orders.empty())
    throw invalid_argument(fmt::format("{} applies to scatter files; '{}' is a traced histogram (microsim trace vndf: "
                                       "compare it with `microsim validate --against`, or with another traced histogram)",
                                       r.analytic ? "--analytic" : "--orders", r.files.front()));
  if (r.files.size() < 2 || r.files.size() > 3)
    throw invalid_argument(fmt::format("compare-scattering compares 2 or 3 traced histograms, got {} ('{}')",
                                       r.files.size(), fmt::join(r.files, "', '")));
  std::vector<TracedInput> inputs{{r.files.front(), input_label(0), std::move(first)}};
  for (std::size_t i = 1; i < r.files.size(); ++i) {
    ComparedFile in = read_compared_file(r.files[i]);
    if (!in.traced)
      throw invalid_argument(fmt::format("'{}' is a scatter file among traced histograms (microsim trace vndf): compare "
                                         "files of one kind", r.files[i]));
    inputs.push_back({r.files[i], input_label(i), std::move(*in.traced)});
  }
  return inputs;
}

TracedComparisonSet compare_traced_inputs(std::vector<TracedInput> inputs, double level) {
  TracedComparisonSet c{std::move(inputs), {}, {}, level, ""};
  const std::vector<TracedInput>& in = c.inputs;
  for (std::size_t i = 0; i < in.size(); ++i)
    for (std::size_t j = i + 1; j < in.size(); ++j)
      c.pairs.push_back({i, j, compare_traced_histograms(in[i].histogram, in[i].name, in[j].histogram, in[j].name,
                                                         effective_entry_options())});
  std::string list;
  std::vector<const LobeComparison*> lobes;
  for (const auto& p : c.pairs)
    for (const TracedComparison& t : p.comparisons) {
      lobes.push_back(&t.lobe);
      if (!t.lobe.chi2)
        list += fmt::format("\n  {}-{} {} binning: {}", in[p.a].label, in[p.b].label, t.binning, t.lobe.insufficient);
    }
  if (!list.empty()) throw invalid_argument("too little data to compare (trace more rays, or fewer --rows):" + list);
  c.family = comparison_family(lobes, level);
  c.note = tile_note(in);
  return c;
}

nlohmann::json family_json(const ComparisonFamily& f, double level) {
  return {{"level", level}, {"tests", f.tests}, {"per_test_significance", f.per_test}, {"rejected", f.rejected}};
}

nlohmann::json chi2_json(const LobeComparison& l, const ComparisonFamily& f) {
  nlohmann::json chi2 = to_json(*l.chi2);
  chi2["rejected"] = l.chi2->p_value < f.per_test;
  chi2["significance"] = f.per_test;
  return chi2;
}

nlohmann::json scatter_input_json(const ScatterInput& in) {
  nlohmann::json j{{"label", in.label}, {"file", in.name}};
  if (in.file.kind == ScatterFileKind::histogram) {
    const ScatterHistogram& h = in.file.histogram;
    j.update({{"kind", "histogram"}, {"producer", h.provenance.producer}, {"measurement", h.provenance.measurement},
              {"paths", h.paths()}, {"partial", h.partial}});
  } else {
    j.update({{"kind", "expectation"}, {"producer", in.file.expectation.producer},
              {"measurement", in.file.expectation.measurement}});
  }
  j["notes"] = in.file.notes;
  return j;
}

nlohmann::json lobe_json(const LobeComparison& l, const std::string& channel, const ComparisonFamily& f) {
  return {{"channel", channel},
          {"order", scatter_order_name(l.order_bin)},
          {"tv", finite_or_null(l.tv)},
          {"tv_noise_floor", finite_or_null(l.tv_noise_floor)},
          {"albedo_a", estimate_json(l.albedo_a)},
          {"albedo_b", estimate_json(l.albedo_b)},
          {"albedo_difference", estimate_json(l.difference)},
          {"albedo_difference_p", l.difference_p},
          {"albedo_rejected", l.difference_p < f.per_test},
          {"chi2", chi2_json(l, f)}};
}

nlohmann::json traced_json(const TracedComparison& c, const ComparisonFamily& f) {
  const LobeComparison& l = c.lobe;
  return {{"binning", c.binning},         {"tv", finite_or_null(l.tv)},
          {"tv_noise_floor", finite_or_null(l.tv_noise_floor)},
          {"hit_fraction_a", estimate_json(l.albedo_a)}, {"hit_fraction_b", estimate_json(l.albedo_b)},
          {"hit_fraction_difference_p", l.difference_p}, {"hit_fraction_rejected", l.difference_p < f.per_test},
          {"chi2", chi2_json(l, f)}};
}

}  // namespace

std::vector<int> parse_scatter_orders(std::string_view text) {
  std::vector<int> orders;
  for (const std::string_view field : reader::split_commas(text)) {
    int k = -2;
    if (field == "total") k = kTotalOrder;
    else if (field == "5+") k = 4;
    else if (field.size() == 1 && field[0] >= '1' && field[0] <= '4') k = field[0] - '1';
    if (k == -2)
      throw invalid_argument(fmt::format("--orders {}: unknown order {} (1, 2, 3, 4, 5+ or total)", quote_excerpt(text),
                                         quote_excerpt(field)));
    if (std::find(orders.begin(), orders.end(), k) != orders.end())
      throw invalid_argument(fmt::format("--orders {}: order {} given twice", quote_excerpt(text), quote_excerpt(field)));
    orders.push_back(k);
  }
  return orders;
}

CompareScatteringResult compare_scattering_files(const CompareScatteringRequest& r, const RunControl& run) {
  if (!(r.level > 0 && r.level < 1)) throw invalid_argument(fmt::format("--level {}: must be in (0, 1)", r.level));
  if (r.files.empty()) throw invalid_argument("compare-scattering compares 2 or 3 results, got no file");
  ComparedFile first = read_compared_file(r.files.front());
  if (first.traced) {
    std::vector<TracedInput> inputs = traced_inputs(r, std::move(*first.traced));
    refuse_repeated_files(r.files);
    return {std::nullopt, compare_traced_inputs(std::move(inputs), r.level)};
  }
  ScatterComparison c;
  c.orders = parse_scatter_orders(r.orders.empty() ? "1,2,3,4,5+,total" : r.orders);
  c.level = r.level;
  c.inputs = scatter_inputs(r, std::move(*first.scatter), run);
  compare_scatter_pairs(c);
  return {std::move(c), std::nullopt};
}

nlohmann::json to_json(const ScatterComparison& c) {
  nlohmann::json j = family_json(c.family, c.level);
  j["inputs"] = nlohmann::json::array();
  for (const ScatterInput& i : c.inputs) j["inputs"].push_back(scatter_input_json(i));
  j["comparisons"] = nlohmann::json::array();
  for (const auto& p : c.pairs) {
    nlohmann::json lobes = nlohmann::json::array();
    for (const LobeComparison& l : p.comparisons)
      lobes.push_back(lobe_json(l, scatter_channel_name(c.inputs[p.a].file, l.channel), c.family));
    j["comparisons"].push_back({{"a", c.inputs[p.a].label}, {"b", c.inputs[p.b].label}, {"lobes", lobes}});
  }
  return j;
}

nlohmann::json to_json(const TracedComparisonSet& c) {
  nlohmann::json j{{"kind", "traced-histograms"}};
  j.update(family_json(c.family, c.level));
  j["inputs"] = nlohmann::json::array();
  for (const TracedInput& i : c.inputs)
    j["inputs"].push_back({{"label", i.label}, {"file", i.name}, {"rays", i.histogram.rays}, {"hits", i.histogram.hits},
                           {"partial", i.histogram.partial}, {"attributes", i.histogram.attributes}});
  j["notes"] = nlohmann::json::array();
  if (!c.note.empty()) j["notes"].push_back(c.note);
  j["comparisons"] = nlohmann::json::array();
  for (const auto& p : c.pairs) {
    nlohmann::json binnings = nlohmann::json::array();
    for (const TracedComparison& t : p.comparisons) binnings.push_back(traced_json(t, c.family));
    j["comparisons"].push_back({{"a", c.inputs[p.a].label}, {"b", c.inputs[p.b].label}, {"binnings", binnings}});
  }
  return j;
}

nlohmann::json to_json(const CompareScatteringResult& r) { return r.scatter ? to_json(*r.scatter) : to_json(*r.traced); }

}  // namespace microsim
