#include "measure/validate_all.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace microsim {

namespace {

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A validation's options in the batch: its own seed, the run's threads, no cancel or progress of its own
// (the batch stops between validations and reports validations done).
ValidationOptions case_options(const ValidationOptions& run_options, std::uint64_t seed) {
  ValidationOptions vo = run_options;
  vo.seed = seed;
  vo.run = RunControl{};
  vo.run.threads = run_options.run.threads;
  return vo;
}

}  // namespace

// ---- references ------------------------------------------------------------------------------------------

std::shared_ptr<const ReferenceDistribution> ZooReferences::get(const ValidationCase& c, int rows) {
  const std::vector<double> configuration = {c.alpha_x, c.alpha_y, c.theta_deg, c.phi_deg};
  if (configuration != configuration_) {
    configuration_ = configuration;
    references_.clear();
  }
  auto& ref = references_[c.sampler->claims];
  if (!ref) {
    const auto t0 = std::chrono::steady_clock::now();
    ref = claimed_reference(*c.sampler, c.ggx(), c.wi(), rows);
    ++count_;
    seconds_ += elapsed(t0);
  }
  return ref;
}

std::string BsdfZooReferences::key(const BsdfValidationCase& c) {
  return fmt::format("{} {} {}", c.alpha, c.theta_deg, c.material().describe());
}

std::string BsdfZooReferences::flux_key(const BsdfValidationCase& c) {
  return fmt::format("{} {}", key(c), describe(c.sampler->convention));
}

void BsdfZooReferences::prepare(const std::vector<BsdfValidationCase>& cases, int rows) {
  const auto t0 = std::chrono::steady_clock::now();
  // The sampling density's binnings once per configuration and material, then its flux once per convention.
  std::map<std::string, std::shared_ptr<const ReferenceDistribution>> directions;
  std::vector<const BsdfValidationCase*> firsts, flux_firsts;
  for (const BsdfValidationCase& c : cases) {
    if (directions.try_emplace(key(c)).second) firsts.push_back(&c);
    if (references_.try_emplace(flux_key(c)).second) flux_firsts.push_back(&c);
  }
  std::vector<std::shared_ptr<const ReferenceDistribution>> computed(firsts.size());
  tbb::parallel_for(std::size_t(0), firsts.size(), [&](std::size_t i) {
    const BsdfValidationCase& c = *firsts[i];
    computed[i] = density_reference(bsdf_sampling_density(c.material(), c.ggx(), c.wi()), c.ggx(), c.wi(), rows);
  });
  for (std::size_t i = 0; i < firsts.size(); ++i) directions[key(*firsts[i])] = computed[i];
  std::vector<BsdfReference> fluxes(flux_firsts.size());
  tbb::parallel_for(std::size_t(0), flux_firsts.size(), [&](std::size_t i) {
    const BsdfValidationCase& c = *flux_firsts[i];
    fluxes[i] = bsdf_reference(directions.at(key(c)), c.material(), c.sampler->convention);
  });
  for (std::size_t i = 0; i < flux_firsts.size(); ++i) references_[flux_key(*flux_firsts[i])] = std::move(fluxes[i]);
  count_ += int(firsts.size());
  seconds_ += elapsed(t0);
}

const BsdfReference& BsdfZooReferences::get(const BsdfValidationCase& c) const { return references_.at(flux_key(c)); }

// ---- the batch -------------------------------------------------------------------------------------------

ZooBatch::ZooBatch(const ValidationRun& run) {
  result_.requested = run.cases.size();
  result_.samples = run.options.samples;
  result_.seed = run.seed;
  result_.precision = run.options.precision;
  result_.significance = run.family_significance;
  result_.per_validation_significance = run.options.significance;
}

ZooSummaryRow& ZooBatch::summary_of(const std::string& sampler, bool negative_control) {
  ZooSummaryRow& sm = summary_[sampler];
  sm.sampler = sampler;
  sm.negative_control = negative_control;
  return sm;
}

const ZooRow& ZooBatch::add(const ValidationCase& c, ValidationReport r) {
  const SamplerInfo& s = *c.sampler;
  ZooSummaryRow& sm = summary_of(std::string(s.name), s.negative_control);
  sm.total += 1;
  sm.passed += r.passed;
  sm.min_p = std::min(sm.min_p, r.p_value);
  sm.max_p = std::max(sm.max_p, r.p_value);
  sm.seconds += r.seconds;
  if (s.negative_control ? (r.passed || !(r.p_value < kNegativeControlP)) : !r.passed) sm.expectation_met = false;
  ZooRow row;
  row.sampler = std::string(s.name);
  row.negative_control = s.negative_control;
  row.alpha_x = c.alpha_x;
  row.alpha_y = c.alpha_y;
  row.theta_deg = c.theta_deg;
  row.phi_deg = c.phi_deg;
  row.verdict = r.passed ? "pass" : (s.negative_control ? "rejected" : "FAIL");
  row.report = std::move(r);
  return result_.rows.emplace_back(std::move(row));
}

void ZooBatch::begin_bsdf_section(std::size_t validations) { result_.requested += validations; }

const ZooRow& ZooBatch::add_bsdf(const BsdfValidationCase& c, ValidationReport r) {
  const BsdfSamplerInfo& s = *c.sampler;
  ZooSummaryRow& sm = summary_of(std::string(s.name), s.negative_control);
  const bool expects_rejection = c.expects_rejection(r.samples);
  const bool without_effect = s.negative_control && !expects_rejection;
  sm.total += 1;
  sm.passed += r.passed;
  sm.without_effect += without_effect;
  sm.min_p = std::min(sm.min_p, r.p_value);
  sm.max_p = std::max(sm.max_p, r.p_value);
  sm.seconds += r.seconds;
  const double weight_p = std::min(r.check("bsdf_albedo").p_value, r.check("bsdf_bins").p_value);
  if (expects_rejection ? (r.passed || !(weight_p < kNegativeControlP)) : (!s.negative_control && !r.passed))
    sm.expectation_met = false;
  ZooRow row;
  row.bsdf = true;
  row.sampler = std::string(s.name);
  row.negative_control = s.negative_control;
  row.alpha_x = row.alpha_y = c.alpha;
  row.theta_deg = c.theta_deg;
  row.inside = c.inside;
  row.bug_has_effect = expects_rejection;
  row.material = c.material().describe();
  row.verdict = r.passed ? (without_effect ? "no effect" : "pass") : (s.negative_control ? "rejected" : "FAIL");
  row.report = std::move(r);
  return result_.rows.emplace_back(std::move(row));
}

ZooResult ZooBatch::finish(bool partial, const ZooReferences& references, const BsdfZooReferences* bsdf_references) {
  ZooResult out = result_;
  out.seconds = elapsed(start_);
  bool all_met = true;
  auto summarise = [&](std::string_view name) {
    const auto it = summary_.find(std::string(name));
    if (it == summary_.end()) return;
    all_met = all_met && it->second.expectation_met;
    out.summary.push_back(it->second);
  };
  for (const SamplerInfo& s : sampler_registry()) summarise(s.name);
  for (const BsdfSamplerInfo& s : bsdf_sampler_registry()) summarise(s.name);
  out.partial = partial;
  out.all_met = all_met && !partial;
  out.references = references.count();
  out.reference_seconds = references.seconds();
  if (bsdf_references) {
    out.bsdf_references = bsdf_references->count();
    out.bsdf_reference_seconds = bsdf_references->seconds();
  }
  return out;
}

// ---- running it --------------------------------------------------------------------------------------------

bool run_bsdf_section(const ValidationRun& run, ZooBatch& batch, BsdfZooReferences& references,
                      const ZooObserver& observer) {
  const std::vector<BsdfValidationCase> cases = bsdf_zoo_cases(run.seed);
  batch.begin_bsdf_section(cases.size());
  if (observer.bsdf_section) observer.bsdf_section(cases.size());
  ValidationOptions vo = case_options(run.options, run.seed);
  vo.significance = sidak_significance(run.family_significance, int(cases.size()));
  references.prepare(cases, vo.rows);
  constexpr const char* kStage = "validate --all: BSDF samplers";
  run.options.run.report(kStage, 0, cases.size());
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (run.options.run.cancelled()) return false;
    const BsdfValidationCase& c = cases[i];
    vo.seed = c.seed;
    vo.convention = c.sampler->convention;  // each sampler's weights in its own transport mode
    const ZooRow& row = batch.add_bsdf(c, validate_bsdf_sampler(*c.sampler, c.material(), c.ggx(), c.wi(), vo,
                                                                &references.get(c)));
    if (observer.row) observer.row(row);
    run.options.run.report(kStage, i + 1, cases.size());
  }
  return true;
}

ZooResult validate_all(const ValidationRun& run, const ZooObserver& observer) {
  require_samples_for_any_test(run.options.samples);
  ZooBatch batch(run);
  ZooReferences references;  // one per configuration and claimed pdf
  constexpr const char* kStage = "validate --all";
  run.options.run.report(kStage, 0, run.cases.size());
  bool partial = false;
  for (std::size_t i = 0; i < run.cases.size() && !partial; ++i) {
    if (run.options.run.cancelled()) {
      partial = true;
      break;
    }
    const ValidationCase& c = run.cases[i];
    const auto ref = references.get(c, run.options.rows);
    const ValidationOptions vo = case_options(run.options, c.seed);  // independent streams per validation
    const auto t_start = std::chrono::steady_clock::now();
    ValidationReport r = validate_sampler(*c.sampler, c.ggx(), c.wi(), vo, ref);
    r.seconds = elapsed(t_start);
    const ZooRow& row = batch.add(c, std::move(r));
    if (observer.row) observer.row(row);
    run.options.run.report(kStage, i + 1, run.cases.size());
  }
  BsdfZooReferences bsdf_references;
  if (!partial) partial = !run_bsdf_section(run, batch, bsdf_references, observer);
  return batch.finish(partial, references, &bsdf_references);
}

// ---- JSON ----------------------------------------------------------------------------------------------------

namespace {

nlohmann::json row_json(const ZooRow& row) {
  nlohmann::json j = to_json(row.report);
  j["negative_control"] = row.negative_control;
  j["theta_deg"] = row.theta_deg;
  j["phi_deg"] = row.phi_deg;
  if (row.bsdf) {
    j["bsdf_sampler"] = true;
    j["bug_has_effect"] = row.bug_has_effect;
    j["material"] = row.material;
    j["side"] = row.inside ? "inside" : "outside";
  }
  return j;
}

nlohmann::json summary_json(const ZooSummaryRow& sm) {
  return {{"sampler", sm.sampler},
          {"negative_control", sm.negative_control},
          {"passed", sm.passed},
          {"total", sm.total},
          {"without_effect", sm.without_effect},
          {"min_p_value", sm.min_p},
          {"max_p_value", sm.max_p},
          {"expectation_met", sm.expectation_met},
          {"seconds", sm.seconds}};
}

}  // namespace

nlohmann::json to_json(const ZooResult& result) {
  nlohmann::json j;
  j["verdict"] = result.verdict();
  j["partial"] = result.partial;
  j["validations_requested"] = result.requested;
  j["validations_done"] = result.rows.size();
  j["samples"] = result.samples;
  j["seed"] = result.seed;
  j["precision"] = to_string(result.precision);
  j["significance"] = result.significance;
  j["per_validation_significance"] = result.per_validation_significance;
  j["negative_control_p_threshold"] = kNegativeControlP;
  j["seconds"] = result.seconds;
  j["reference_seconds"] = result.reference_seconds;
  j["summary"] = nlohmann::json::array();
  for (const ZooSummaryRow& sm : result.summary) j["summary"].push_back(summary_json(sm));
  j["results"] = nlohmann::json::array();
  for (const ZooRow& row : result.rows) j["results"].push_back(row_json(row));
  return j;
}

int exit_code(const ZooResult& result) { return result.partial ? 130 : result.all_met ? 0 : 1; }

}  // namespace microsim
