// What a `microsim run` directory measured, read back for comparing two runs bit for bit: results.json without
// timings and the host's rates, every VNDF histogram (counts, probabilities, attributes but the rate), every
// scattering file's exact sums, every CSV table. Shared by the shard/merge and the mpirun tests.
#pragma once

#include "cli_helpers.h"

#include "stats/histogram_io.h"
#include "stats/scatter_io.h"

#include <nlohmann/json.hpp>

#include <string>

namespace microsim::test {

// The spec both compare: a VNDF and a per-order scattering measurement of one glass (split over ranks or
// shards), a walk albedo table (its 4 cells split likewise) and a validation of heitz2018 (3 blocks of
// samples: split over ranks, run by the merge of shards).
inline std::string split_spec(const std::string& name, int seed) {
  return "name = \"" + name + "\"\nseed = " + std::to_string(seed) + R"(

[[material]]
name = "glass"
alphas = [0.4]
type = "dielectric"
eta = 1.5

[[quantity]]
kind = "vndf"
material = "glass"
theta = [30]
rows = 7
target_tv = 0.03

[[quantity]]
kind = "scattering"
material = "glass"
orders = "all"
theta = [50]
target_tv = 0.055

[[quantity]]
kind = "albedo"
material = "glass"
orders = "all"
mus = 4
target_relative_error = 0.02

[[material]]
name = "ggx"
alphas = [0.3]
type = "mirror"

[[quantity]]
kind = "validation"
material = "ggx"
sampler = "heitz2018"
theta = [40]
rows = 7
detect_tv = 0.01
)";
}

// results.json without what differs between two runs of the same seed: timings and rates (a surface's reason
// states how long its build took).
inline nlohmann::json without_timings(nlohmann::json doc) {
  if (doc.is_object()) {
    nlohmann::json out = nlohmann::json::object();
    for (auto& [key, value] : doc.items())
      if (key.find("seconds") == std::string::npos && key != "rays_per_second") out[key] = without_timings(value);
    if (out.contains("surface") && out["surface"].is_object()) out["surface"].erase("reason");
    return out;
  }
  if (doc.is_array())
    for (auto& item : doc) item = without_timings(item);
  return doc;
}

inline std::string histogram_contents(const fs::path& path) {
  TracedHistogram h = read_histogram_exr(path);
  h.attributes.erase("rays_per_second");
  return nlohmann::json(h.counts).dump() + nlohmann::json(h.probability).dump() + nlohmann::json(h.attributes).dump();
}

inline std::string scatter_contents(const fs::path& path) {
  const ScatterFile f = read_scatter_exr(path);
  std::string out;
  for (int c = 0; c < f.histogram.channels(); ++c)
    for (int k = 0; k < kScatterOrderBins; ++k)
      for (std::size_t b = 0; b < f.histogram.bins(); ++b) {
        const Histogram& h = f.histogram.histogram(c, k);
        out += std::to_string(h.exact_weight(b).low_bits()) + "," + std::to_string(h.exact_weight_squared(b).low_bits()) + ",";
      }
  return out + f.histogram.provenance.blocks.to_string() + std::to_string(f.histogram.paths());
}

// Whether some round of the run in DIR (its first rounds only, with `first_only`) has a block count (4096 rays
// or paths per block) that `parts` do not divide: a split into that many parts is uneven.
inline bool has_uneven_round(const fs::path& dir, int parts, bool first_only = false) {
  const nlohmann::json doc = nlohmann::json::parse(slurp(dir / "results.json"));
  for (const auto& m : doc.at("results").at("measurements"))
    for (const auto& r : m.value("rounds", nlohmann::json::array())) {
      const std::uint64_t units = r.at("units"), blocks = (units + 4095) / 4096;
      if (blocks % std::uint64_t(parts) != 0) return true;
      if (first_only) break;
    }
  return false;
}

inline std::string run_directory_contents(const fs::path& dir) {
  std::string out = without_timings(nlohmann::json::parse(slurp(dir / "results.json"))).dump();
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("vndf-", 0) == 0) out += name + histogram_contents(entry.path());
    else if (name.rfind("scattering-", 0) == 0) out += name + scatter_contents(entry.path());
    else if (name.size() > 4 && name.substr(name.size() - 4) == ".csv") out += name + slurp(entry.path());
  }
  return out;
}

}  // namespace microsim::test
