// experiment: a whole experiment in the shards of a job array (shards.h).
#include "experiment/shards.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/fnv1a.h"
#include "core/parse.h"
#include "core/run_control.h"
#include "experiment/run.h"
#include "experiment/run_directory.h"

#include <fmt/core.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace microsim::experiment {
namespace {

namespace fs = std::filesystem;

std::string part_file(std::size_t task) { return fmt::format("part-{}.bin", task); }

// shard.json records each part's, so a part changed after it was written is refused.
std::string part_digest(const std::string& bytes) { return fmt::format("{:016x}", fnv1a(bytes)); }

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The form of the parts a shard holds (parts.h): 3 since they carry the library's part JSON of each kind
// (vndf_part_json, scatter_part_json, masking_part_json, validation_part_json, albedo_part_json); a shard of
// another is refused.
constexpr int kPartsVersion = 3;

[[noreturn]] void bad_shard(const fs::path& dir, const std::string& what) {
  throw std::invalid_argument(fmt::format("--merge {}: {}", quote_excerpt(dir.string()), what));
}

nlohmann::json shard_json(const ExperimentSpec& spec, const ShardParts& shard) {
  nlohmann::json tasks = nlohmann::json::array();
  for (std::size_t t = 0; t < shard.tasks.size(); ++t)
    tasks.push_back({{"round", round_task_json(shard.tasks[t])}, {"file", part_file(t)}, {"bytes", shard.parts[t].size()},
                     {"digest", part_digest(shard.parts[t])}});
  return {{"format", "microsim experiment shard"}, {"parts_version", kPartsVersion},
          {"spec", {{"name", spec.name}, {"digest", shard.spec_digest}, {"inputs", shard.inputs}}},
          {"seed", shard.seed}, {"shard", {shard.k, shard.n}}, {"plan", shard.plan}, {"rounds", tasks}};
}

// The shard's input files: each as the merge finds it (a heightmap or dump replaced between the shards and the
// merge would mix parts measured from different files).
void check_inputs(const fs::path& dir, const nlohmann::json& recorded, const nlohmann::json& inputs) {
  for (const auto& [key, digest] : inputs.items())
    if (!recorded.contains(key) || recorded.at(key) != digest)
      bad_shard(dir, fmt::format("{} has changed since the shard ran (digest {}, now {}): run the shard jobs again",
                                 key, recorded.contains(key) ? recorded.at(key).dump() : "none", digest.dump()));
}

// The shard's identity: its spec, seed and input files must be the merge's.
void check_identity(const fs::path& dir, const nlohmann::json& doc, const ExperimentSpec& spec, std::uint64_t seed,
                    const nlohmann::json& inputs) {
  if (doc.value("format", "") != "microsim experiment shard") bad_shard(dir, "shard.json is not a microsim experiment shard");
  if (const int v = doc.value("parts_version", 1); v != kPartsVersion)
    bad_shard(dir, fmt::format("its parts are of version {}, this microsim reads version {} (written by another "
                               "version of microsim: run its shard jobs again with this one)", v, kPartsVersion));
  const std::string digest = doc.at("spec").at("digest").get<std::string>();
  if (digest != spec_digest(spec))
    bad_shard(dir, fmt::format("a shard of another spec (digest {}; {} has {})", digest, spec.source, spec_digest(spec)));
  const auto shard_seed = doc.at("seed").get<std::uint64_t>();
  if (shard_seed != seed) bad_shard(dir, fmt::format("a shard of seed {}, not {} (give --seed {})", shard_seed, seed, shard_seed));
  check_inputs(dir, doc.at("spec").value("inputs", nlohmann::json::object()), inputs);
}

ShardParts shard_from_json(const fs::path& dir, const nlohmann::json& doc) {
  ShardParts shard;
  shard.seed = doc.at("seed").get<std::uint64_t>();
  shard.spec_digest = doc.at("spec").at("digest").get<std::string>();
  shard.inputs = doc.at("spec").value("inputs", nlohmann::json::object());
  shard.k = doc.at("shard").at(0).get<std::uint64_t>();
  shard.n = doc.at("shard").at(1).get<std::uint64_t>();
  if (shard.n == 0 || shard.k == 0 || shard.k > shard.n) bad_shard(dir, fmt::format("shard {}/{} is not K/N with 1 <= K <= N", shard.k, shard.n));
  shard.plan = doc.at("plan");
  for (const nlohmann::json& r : doc.at("rounds")) {
    shard.tasks.push_back(round_task_from_json(r.at("round")));
    const fs::path file = dir / r.at("file").get<std::string>();
    if (r.at("file").get<std::string>() != part_file(shard.parts.size())) bad_shard(dir, fmt::format("unexpected part file {}", file.filename().string()));
    shard.parts.push_back(read_bytes(file));
    if (!fs::is_regular_file(file) || shard.parts.back().size() != r.at("bytes").get<std::size_t>() ||
        part_digest(shard.parts.back()) != r.at("digest").get<std::string>())
      bad_shard(dir, fmt::format("{} is missing, or not what shard.json records (size, digest)", file.filename().string()));
    try {
      check_whole_part(shard.parts.back(), shard.tasks.back(), int(shard.k - 1), int(shard.n));
    } catch (const InternalError& e) {
      bad_shard(dir, e.what());
    }
  }
  return shard;
}

// Every shard of one job: the same N, plan and tasks as the first.
void check_same_job(const ShardParts& a, const ShardParts& b, const std::string& name) {
  if (b.n != a.n) throw std::invalid_argument(fmt::format("--merge {}: a shard of {} (K/{}), the first of {}", name, b.n, b.n, a.n));
  if (b.tasks != a.tasks || b.plan.at("decisions").size() != a.plan.at("decisions").size())
    throw std::invalid_argument(fmt::format("--merge {}: its plan's first rounds differ from the first shard's (not the same run)", name));
}

}  // namespace

ShardParts run_shard(const ExperimentSpec& spec, const ExperimentPlan& plan, std::uint64_t seed, std::uint64_t k,
                     std::uint64_t n, const RunControl& run, SurfaceCache& surfaces) {
  ShardParts shard{k, n, seed, spec_digest(spec), input_digests(spec), plan_json(plan, spec),
                   first_split_rounds(spec, plan, seed), {}};
  for (const RoundTask& task : shard.tasks) {
    shard.parts.push_back(run_part(spec, plan, task, int(k - 1), int(n), run, surfaces));
    if (part_is_partial(shard.parts.back())) throw Cancelled("a shard keeps nothing when interrupted");
  }
  return shard;
}

void write_shard_directory(const fs::path& dir, const ExperimentSpec& spec, const ShardParts& shard) {
  if (fs::exists(dir) && (!fs::is_directory(dir) || !fs::is_empty(dir)))
    throw std::invalid_argument(fmt::format("--out {}: a shard's directory must be new or empty", quote_excerpt(dir.string())));
  fs::create_directories(dir);
  for (std::size_t t = 0; t < shard.parts.size(); ++t) write_file_atomically(dir / part_file(t), shard.parts[t]);
  write_file_atomically(dir / "shard.json", shard_json(spec, shard).dump(1) + "\n");
}

ShardParts read_shard_directory(const fs::path& dir, const ExperimentSpec& spec, std::uint64_t seed,
                                const nlohmann::json& inputs) {
  if (!fs::is_regular_file(dir / "shard.json")) bad_shard(dir, "holds no shard.json (not a `run --shard K/N` directory)");
  try {
    const nlohmann::json doc = nlohmann::json::parse(read_bytes(dir / "shard.json"));
    check_identity(dir, doc, spec, seed, inputs);
    return shard_from_json(dir, doc);
  } catch (const nlohmann::json::exception& e) {
    bad_shard(dir, fmt::format("shard.json is malformed: {}", e.what()));
  }
}

StoredRounds merge_shards(const std::vector<ShardParts>& shards, const std::vector<std::string>& names) {
  if (shards.empty()) throw std::invalid_argument("--merge: no shard given");
  const std::uint64_t n = shards.front().n;
  std::vector<int> given(std::size_t(n), -1);
  for (std::size_t i = 0; i < shards.size(); ++i) {
    check_same_job(shards.front(), shards[i], names[i]);
    int& slot = given[std::size_t(shards[i].k - 1)];
    if (slot >= 0)
      throw std::invalid_argument(fmt::format("--merge: shard {}/{} given twice ({} and {})", shards[i].k, n, names[std::size_t(slot)], names[i]));
    slot = int(i);
  }
  for (std::uint64_t k = 1; k <= n; ++k)
    if (given[std::size_t(k - 1)] < 0) throw std::invalid_argument(fmt::format("--merge: shard {}/{} is missing", k, n));
  StoredRounds stored{shards.front().tasks, {}};
  for (std::size_t t = 0; t < stored.tasks.size(); ++t) {
    stored.parts.emplace_back();
    for (const int i : given) stored.parts.back().push_back(shards[std::size_t(i)].parts[t]);
  }
  return stored;
}

}  // namespace microsim::experiment
