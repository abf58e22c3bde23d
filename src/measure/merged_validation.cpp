// The merge of a validate run's parts analysed as the single run (validate_all.h).
#include "measure/validate_all.h"

#include "stats/histogram_io.h"

#include <fmt/core.h>

namespace microsim {

namespace {

ZooResult merged_batch(const ValidationRun& run, const ValidationPart& merged, const RunControl& control,
                       const ZooObserver& observer) {
  ZooBatch batch(run);
  ZooReferences references;
  for (std::size_t i = 0; i < run.cases.size(); ++i) {
    const ValidationCase& c = run.cases[i];
    ValidationOptions o = run.options;
    o.seed = c.seed;
    const auto ref = references.get(c, o.rows);
    require_samples(o.samples, *ref);
    ValidationReport r = report_drawn_samples(*c.sampler, *ref, merged.tallies[i], o);
    r.seconds = merged.seconds[i];
    const ZooRow& row = batch.add(c, std::move(r));
    if (observer.row) observer.row(row);
  }
  BsdfZooReferences bsdf_references;
  ValidationRun bsdf_run = run;
  bsdf_run.options.run = control;
  const bool partial = !run_bsdf_section(bsdf_run, batch, bsdf_references, observer);
  return batch.finish(partial, references, &bsdf_references);
}

void merged_single(MergedValidation& m, const ValidationPart& merged) {
  const ValidationCase& c = m.run.cases.front();
  ValidationOptions o = m.run.options;
  o.seed = c.seed;
  if (m.run.against.empty()) {
    const auto ref = claimed_reference(*c.sampler, c.ggx(), c.wi(), o.rows);
    require_samples(o.samples, *ref);
    m.report = report_drawn_samples(*c.sampler, *ref, merged.tallies.front(), o);
  } else {
    m.traced = read_histogram_exr(m.run.against);
    if (traced_histogram_digest(*m.traced) != merged.parameters.value("against_digest", ""))
      throw HistogramMergeError(fmt::format("'{}' is not the traced histogram the parts were compared with (its "
                                            "counts differ)", m.run.against));
    m.report = report_drawn_samples_against_trace(*c.sampler, c.ggx(), c.wi(), merged.tallies.front(), o, *m.traced);
  }
  m.report->seconds = merged.seconds.front();
}

}  // namespace

MergedValidation analyse_merged_validation(const ValidationPart& merged, const RunControl& control,
                                           const ZooObserver& observer) {
  MergedValidation m;
  m.run = validation_run_of(merged);
  if (m.run.batch) m.batch = merged_batch(m.run, merged, control, observer);
  else merged_single(m, merged);
  return m;
}

nlohmann::json merged_validation_json(const MergedValidation& m) {
  if (m.batch) return to_json(*m.batch);
  nlohmann::json j = to_json(*m.report);
  if (m.traced) {
    j["against"] = m.run.against;
    j["oracle_rays"] = m.traced->rays;
    j["oracle_hits"] = m.traced->hits;
  }
  return j;
}

}  // namespace microsim
