#include "measure/validation.h"

#include "core/fnv1a.h"

#include <fmt/core.h>

#include <chrono>
#include <cstring>
#include <stdexcept>

namespace microsim {

namespace {

constexpr const char* kValidationProducer = "validate";
const PartReader kValidationReader(kValidationProducer);

// The cells of each binning the samples are counted in (bins and the remainder cell): the sphere and lobe
// binnings of `rows` rows, or the traced histogram's.
nlohmann::json tally_cells(int rows, const TracedHistogram* traced) {
  if (!traced) {
    const std::size_t bins = std::size_t(DirectionBinning::sphere(rows).size()) + 1;
    return nlohmann::json::array({bins, bins});  // the sphere and lobe binnings of `rows` rows have as many bins
  }
  nlohmann::json cells = nlohmann::json::array();
  for (const DirectionBinning& b : traced->binnings) cells.push_back(std::size_t(b.size()) + 1);
  return cells;
}

std::vector<std::size_t> cells_of(const nlohmann::json& parameters) {
  const nlohmann::json& cells = kValidationReader.member(parameters, "cells", "provenance/parameters");
  std::vector<std::size_t> out;
  if (!cells.is_array() || cells.empty() || cells.size() > 8)
    kValidationReader.malformed("provenance/parameters/cells", "is not a list of binnings' cells");
  for (const nlohmann::json& c : cells) {
    if (!c.is_number_unsigned() || c.get<std::uint64_t>() < 2 || c.get<std::uint64_t>() > 2ull * kMaxBinningRows * kMaxBinningRows + 1)
      kValidationReader.malformed("provenance/parameters/cells", "is not a list of binnings' cells");
    out.push_back(c.get<std::size_t>());
  }
  return out;
}

// Everything that defines the run but the seed and the blocks.
nlohmann::json run_parameters(const ValidationRun& run, const TracedHistogram* traced) {
  const ValidationOptions& o = run.options;
  nlohmann::json p = {{"mode", run.batch ? "all" : "sampler"},
                      {"samples", o.samples},
                      {"rows", o.rows},
                      {"precision", to_string(o.precision)},
                      {"significance", run.family_significance},
                      {"block_size", kSampleBlock},
                      {"cells", tally_cells(o.rows, traced)}};
  if (run.batch) {
    nlohmann::json samplers = nlohmann::json::array();
    for (const SamplerInfo& s : sampler_registry()) samplers.push_back(std::string(s.name));
    p["samplers"] = samplers;
    p["validations"] = run.cases.size();
    return p;
  }
  const ValidationCase& c = run.cases.front();
  p["sampler"] = std::string(c.sampler->name);
  p["alpha"] = {c.alpha_x, c.alpha_y};
  p["theta"] = c.theta_deg;
  p["phi"] = c.phi_deg;
  p["against"] = run.against;
  if (traced) p["against_digest"] = traced_histogram_digest(*traced);
  return p;
}

ValidationOptions case_options(const ValidationRun& run, const ValidationCase& c, BlockRange blocks) {
  ValidationOptions o = run.options;
  o.seed = c.seed;
  o.blocks = blocks;
  return o;
}

battery::Tally tally_case(const ValidationRun& run, const ValidationCase& c, BlockRange blocks,
                          const TracedHistogram* traced) {
  const ValidationOptions o = case_options(run, c, blocks);
  if (traced) return tally_drawn_samples_for_trace(*c.sampler, c.ggx(), c.wi(), o, *traced);
  return tally_drawn_samples(*c.sampler, *claimed_reference_bins(*c.sampler, c.ggx(), c.wi(), o.rows), o);
}

const SamplerInfo& sampler_named(const std::string& name) {
  const SamplerInfo* s = find_sampler(name);
  if (!s) kValidationReader.malformed("provenance/parameters/sampler", fmt::format("'{}' is not a sampler of this build", name));
  return *s;
}

}  // namespace

std::vector<ValidationCase> zoo_cases(std::uint64_t seed) {
  std::vector<ValidationCase> cases;
  for (const ZooRoughness& a : kZooRoughness)
    for (const double theta : kZooThetas)
      for (const SamplerInfo& s : sampler_registry())
        cases.push_back({&s, a.alpha_x, a.alpha_y, theta, a.phi_deg, seed + std::uint64_t(cases.size())});
  return cases;
}

bool BsdfValidationCase::expects_rejection(std::uint64_t samples) const {
  if (!sampler->negative_control) return false;
  if (!sampler->bug_has_effect) return true;
  return sampler->bug_has_effect(ggx(), sampler_index(material()), wi(), samples);
}

std::vector<BsdfValidationCase> bsdf_zoo_cases(std::uint64_t seed) {
  std::vector<BsdfValidationCase> cases;
  for (const double alpha : kBsdfZooAlphas)
    for (const double theta : kBsdfZooThetas)
      for (const bool inside : {false, true})
        for (const BsdfSamplerInfo& s : bsdf_sampler_registry())
          if (!inside || s.material == MaterialKind::dielectric)
            cases.push_back({&s, alpha, theta, inside, seed + 1000000 + std::uint64_t(cases.size())});
  return cases;
}

std::uint64_t validation_blocks(const ValidationRun& run) { return BlockPlan{run.options.samples, kSampleBlock}.blocks(); }

std::string traced_histogram_digest(const TracedHistogram& t) {
  std::uint64_t h = 1469598103934665603ull;
  for (const DirectionBinning& b : t.binnings) {
    const std::string d = b.describe().dump();
    h = fnv1a(h, d.data(), d.size());
  }
  for (const std::vector<std::uint64_t>& c : t.counts) h = fnv1a(h, c.data(), c.size() * sizeof(std::uint64_t));
  h = fnv1a(h, &t.rays, sizeof t.rays);
  h = fnv1a(h, &t.hits, sizeof t.hits);
  return fmt::format("{:016x}", h);
}

ValidationPart sample_validation_part(const ValidationRun& run, BlockRange blocks, const TracedHistogram* traced) {
  if (run.cases.empty()) throw std::invalid_argument("sample_validation_part: no validation");
  if (!run.batch && run.cases.size() != 1) throw std::invalid_argument("sample_validation_part: a run of one validation");
  if (!run.against.empty() && (!traced || run.batch))
    throw std::invalid_argument("sample_validation_part: a comparison with a traced histogram is one validation");
  const BlockPlan plan{run.options.samples, kSampleBlock};
  ValidationPart part;
  part.parameters = run_parameters(run, traced);
  part.provenance = {kValidationProducer, part.parameters.dump(), run.seed, plan.blocks(), selected_blocks(plan, blocks)};
  for (std::size_t i = 0; i < run.cases.size(); ++i) {
    const auto start = std::chrono::steady_clock::now();
    part.tallies.push_back(tally_case(run, run.cases[i], part.provenance.blocks, traced));
    part.seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    run.options.run.report("validations", i + 1, run.cases.size());
  }
  return part;
}

nlohmann::json validation_part_json(const ValidationPart& part) {
  nlohmann::json tallies = nlohmann::json::array();
  for (const battery::Tally& t : part.tallies) tallies.push_back(tally_json(t));
  return {{"provenance", provenance_json(part.provenance, part.parameters)},
          {"tallies", tallies},
          {"seconds", part.seconds}};
}

bool is_validation_part(const nlohmann::json& report) { return producer_of(report) == kValidationProducer; }

ValidationPart read_validation_part(const nlohmann::json& report) {
  ValidationPart part;
  part.provenance = kValidationReader.provenance(report, part.parameters);
  const ValidationRun run = validation_run_of(part);
  if (part.provenance.total_blocks != validation_blocks(run))
    kValidationReader.malformed("provenance/total_blocks", fmt::format("is not the {} blocks of {} samples", validation_blocks(run),
                                                             run.options.samples));
  const nlohmann::json& tallies = kValidationReader.array(report, "tallies", run.cases.size(), "");
  for (std::size_t i = 0; i < tallies.size(); ++i)
    part.tallies.push_back(tally_from_json(tallies[i], cells_of(part.parameters), part.provenance.blocks.size(),
                                           kValidationReader, fmt::format("tallies/{}", i)));
  part.seconds.assign(run.cases.size(), 0.0);
  const nlohmann::json& seconds = kValidationReader.array(report, "seconds", run.cases.size(), "");
  for (std::size_t i = 0; i < seconds.size(); ++i)
    if (seconds[i].is_number()) part.seconds[i] = seconds[i].get<double>();
  return part;
}

ValidationPart merge_validation_parts(const std::vector<ValidationPart>& parts) {
  const std::vector<std::size_t> order = check_parts_of_one_run(parts);
  ValidationPart merged = parts.front();
  merged.provenance.blocks = {0, merged.provenance.total_blocks};
  for (std::size_t c = 0; c < merged.tallies.size(); ++c) {
    std::vector<const battery::Tally*> in_order;
    merged.seconds.at(c) = 0;
    for (const std::size_t i : order) {
      in_order.push_back(&parts[i].tallies.at(c));
      merged.seconds[c] += parts[i].seconds.at(c);
    }
    merged.tallies[c] = merge_tallies(in_order);
  }
  return merged;
}

ValidationRun validation_run_of(const ValidationPart& part) {
  const nlohmann::json& p = part.parameters;
  const std::string w = "provenance/parameters";
  ValidationRun run;
  const std::string mode = kValidationReader.text(p, "mode", w);
  if (mode != "all" && mode != "sampler") kValidationReader.malformed(w + "/mode", "is neither \"all\" nor \"sampler\"");
  run.batch = mode == "all";
  run.seed = part.provenance.seed;
  run.options.samples = kValidationReader.count(p, "samples", w);
  run.options.rows = int(kValidationReader.count(p, "rows", w));
  if (run.options.rows < 1 || run.options.rows > kMaxBinningRows || run.options.rows % 2 == 0)
    kValidationReader.malformed(w + "/rows", "is not an odd number of rows");
  const std::string precision = kValidationReader.text(p, "precision", w);
  run.options.precision = precision == "float" ? Precision::float32 : Precision::float64;
  run.family_significance = kValidationReader.real(p, "significance", w);
  if (kValidationReader.count(p, "block_size", w) != kSampleBlock) kValidationReader.malformed(w + "/block_size", "is not this build's");
  if (run.batch) {
    run.cases = zoo_cases(run.seed);
    nlohmann::json samplers = nlohmann::json::array();
    for (const SamplerInfo& s : sampler_registry()) samplers.push_back(std::string(s.name));
    if (kValidationReader.member(p, "samplers", w) != samplers || kValidationReader.count(p, "validations", w) != run.cases.size())
      kValidationReader.malformed(w + "/samplers", "are not the zoo of this build");
    run.options.significance = sidak_significance(run.family_significance, int(run.cases.size()));
    return run;
  }
  const nlohmann::json& alpha = kValidationReader.array(p, "alpha", 2, w);
  if (!alpha[0].is_number() || !alpha[1].is_number()) kValidationReader.malformed(w + "/alpha", "is not two numbers");
  run.cases = {{&sampler_named(kValidationReader.text(p, "sampler", w)), alpha[0].get<double>(), alpha[1].get<double>(),
                kValidationReader.real(p, "theta", w), kValidationReader.real(p, "phi", w), run.seed}};
  run.against = kValidationReader.text(p, "against", w);
  run.options.significance = run.family_significance;
  return run;
}

}  // namespace microsim
