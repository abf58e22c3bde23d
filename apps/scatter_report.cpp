#include "scatter_report.h"

#include "command.h"

#include "core/atomic_file.h"
#include "measure/scatter.h"
#include "stats/scatter_merge.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>
#include <cstdlib>
#include <nlohmann/json.hpp>

namespace microsim::app {

namespace {

// What the geometric upper hemisphere holds: light from above (note theta < 90) is reflected into it (and
// transmitted into the lower one), light from inside a dielectric (theta > 90) is transmitted into it.
enum class UpperHemisphere { unknown, reflected, transmitted };

UpperHemisphere upper_hemisphere(const std::map<std::string, std::string>& notes) {
  const auto it = notes.find("theta");
  if (it == notes.end()) return UpperHemisphere::unknown;
  return std::strtod(it->second.c_str(), nullptr) > 90 ? UpperHemisphere::transmitted : UpperHemisphere::reflected;
}

struct HemisphereLabels {
  std::string upper, lower;
};
HemisphereLabels hemisphere_labels(UpperHemisphere u) {
  switch (u) {
    case UpperHemisphere::reflected: return {"upper (R)", "lower (T)"};
    case UpperHemisphere::transmitted: return {"upper (T)", "lower (R)"};
    default: return {"upper", "lower"};
  }
}

std::string scatter_estimate_text(const Estimate& e) { return fmt::format("{:.6f} +- {:.6f}", e.value, e.standard_error); }

void print_histogram_table(const ScatterHistogram& h, const HemisphereLabels& l) {
  fmt::print("{:<8} {:<11} {:>24} {:>24} {:>24}\n", "channel", "order", l.upper, l.lower, "total");
  for (int c = 0; c < h.channels(); ++c) {
    for (int k : {0, 1, 2, 3, 4, kTotalOrder})
      fmt::print("{:<8} {:<11} {:>24} {:>24} {:>24}\n", h.channel_name(c), scatter_order_name(k),
                 scatter_estimate_text(h.albedo(c, k, ScatterSide::reflected)), scatter_estimate_text(h.albedo(c, k, ScatterSide::transmitted)),
                 scatter_estimate_text(h.albedo(c, k)));
    fmt::print("{:<8} {:<11} {:>24} {:>24}\n", h.channel_name(c), "", "unfinished " + scatter_estimate_text(h.unfinished(c)),
               "lost " + scatter_estimate_text(h.lost(c)));
  }
}

}  // namespace

int report_scatter(const ScatterHistogram& h, const std::map<std::string, std::string>& notes, const ScatterOutputs& o) {
  if (o.part) write_file_atomically(o.out, scatter_part_json(h, notes).dump() + "\n");
  else write_scatter_exr(o.out, h, notes);
  const UpperHemisphere upper = upper_hemisphere(notes);
  const nlohmann::json j = scatter_report_json(scatter_summary_json(h), notes);
  if (!o.json.empty()) write_file_atomically(o.json, j.dump(2) + "\n");
  fmt::print("{}: {} paths, blocks {} of {}{}\n", h.provenance.producer, h.paths(), h.provenance.blocks.to_string(),
             h.provenance.total_blocks, h.partial ? " (partial)" : "");
  print_histogram_table(h, hemisphere_labels(upper));
  if (h.partial)
    fmt::print(stderr, "{}: interrupted: the {} paths of blocks {} are written to {}, marked partial\n",
               h.provenance.producer, h.paths(), h.provenance.blocks.to_string(), o.out);
  return h.partial ? kExitInterrupted : kExitOk;
}

int report_scatter(const ScatterExpectation& e, const std::map<std::string, std::string>& notes, const ScatterOutputs& o) {
  write_scatter_exr(o.out, e, notes);
  const UpperHemisphere upper = upper_hemisphere(notes);
  const HemisphereLabels labels = hemisphere_labels(upper);
  const nlohmann::json j = scatter_report_json(scatter_summary_json(e), notes);
  if (!o.json.empty()) write_file_atomically(o.json, j.dump(2) + "\n");
  fmt::print("{}: single scattering, {}\n", e.producer, e.measurement);
  fmt::print("{:<8} {:<11} {:>12} {:>12} {:>12} {:>12}\n", "channel", "order", labels.upper, labels.lower, "total",
             "cubature err");
  for (const nlohmann::json& c : j["channels"]) {
    const nlohmann::json& a = c["albedo"]["order1"];
    fmt::print("{:<8} {:<11} {:>12.6f} {:>12.6f} {:>12.6f} {:>12.2g}\n", c["name"].get<std::string>(), "order1",
               a["upper"]["value"].get<double>(), a["lower"]["value"].get<double>(),
               a["both"]["value"].get<double>(), c["error_estimate"].get<double>());
  }
  return kExitOk;
}

}  // namespace microsim::app
