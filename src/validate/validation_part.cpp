#include "validate/validation_part.h"

#include <fmt/core.h>

#include <cmath>

namespace microsim {

battery::Tally tally_drawn_samples(const SamplerInfo& sampler, const ReferenceDistribution& ref,
                                   const ValidationOptions& options) {
  return battery::tally_samples(battery::drawn_samples(sampler, ref.ggx, ref.wi, options), {&ref.sphere, &ref.lobe},
                                options, &ref);
}

ValidationReport report_drawn_samples(const SamplerInfo& sampler, const ReferenceDistribution& ref,
                                      const battery::Tally& tally, const ValidationOptions& options) {
  return battery::analytic_report(battery::drawn_samples(sampler, ref.ggx, ref.wi, options), tally,
                                  battery::analytic_expectations(ref), ref, options);
}

// ---- tallies as JSON ----------------------------------------------------------------------------------------

namespace {

nlohmann::json checks_json(const battery::PdfChecks& c) {
  const Vec3<double>& d = c.worst_direction;
  return {{"n", exact_real_json(c.weight.n)},
          {"mean", exact_real_json(c.weight.mean)},
          {"m2", exact_real_json(c.weight.m2)},
          {"worst", exact_real_json(c.pdf_worst)},
          {"worst_index", c.pdf_worst_index},
          {"outliers", c.pdf_outliers},
          {"direction", {exact_real_json(d.x()), exact_real_json(d.y()), exact_real_json(d.z())}},
          {"returned", exact_real_json(c.worst_returned)},
          {"cancellation", exact_sum_json(c.weight_cancellation)}};
}

battery::PdfChecks checks_from_json(const nlohmann::json& j, const PartReader& reader, const std::string& where) {
  battery::PdfChecks c;
  c.weight.n = reader.exact_real(j, "n", where);
  c.weight.mean = reader.exact_real(j, "mean", where);
  c.weight.m2 = reader.exact_real(j, "m2", where);
  c.pdf_worst = reader.exact_real(j, "worst", where);
  c.pdf_worst_index = reader.count(j, "worst_index", where);
  c.pdf_outliers = reader.count(j, "outliers", where);
  const nlohmann::json& d = reader.array(j, "direction", 3, where);
  c.worst_direction = {reader.exact_real(d[0], where + "/direction/0"), reader.exact_real(d[1], where + "/direction/1"),
                       reader.exact_real(d[2], where + "/direction/2")};
  c.worst_returned = reader.exact_real(j, "returned", where);
  c.weight_cancellation = reader.exact_sum(reader.member(j, "cancellation", where), where + "/cancellation");
  return c;
}

// The integer counts of one binning's cells (a tally holds them as doubles, exactly).
nlohmann::json counts_json(const std::vector<double>& counts) {
  nlohmann::json a = nlohmann::json::array();
  for (const double c : counts) a.push_back(std::uint64_t(c));
  return a;
}

std::vector<double> counts_from_json(const nlohmann::json& a, const PartReader& reader, const std::string& where) {
  std::vector<double> counts;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_number_unsigned()) reader.malformed(fmt::format("{}/{}", where, i), "is not a count");
    counts.push_back(double(a[i].get<std::uint64_t>()));
  }
  return counts;
}

}  // namespace

nlohmann::json tally_json(const battery::Tally& t) {
  nlohmann::json counts = nlohmann::json::array(), checks = nlohmann::json::array();
  for (const std::vector<double>& c : t.counts) counts.push_back(counts_json(c));
  for (const battery::PdfChecks& c : t.block_checks) checks.push_back(checks_json(c));
  return {{"samples", t.samples}, {"failed", t.failed}, {"outside", t.outside}, {"has_pdf", t.has_pdf},
          {"counts", counts},     {"checks", checks}};
}

battery::Tally tally_from_json(const nlohmann::json& j, const std::vector<std::size_t>& cells, std::uint64_t blocks,
                               const PartReader& reader, const std::string& where) {
  battery::Tally t;
  t.samples = reader.count(j, "samples", where);
  t.failed = reader.count(j, "failed", where);
  t.outside = reader.count(j, "outside", where);
  t.has_pdf = reader.flag(j, "has_pdf", where);
  const nlohmann::json& counts = reader.array(j, "counts", cells.size(), where);
  for (std::size_t k = 0; k < cells.size(); ++k) {
    const std::string w = fmt::format("{}/counts/{}", where, k);
    if (!counts[k].is_array() || counts[k].size() != cells[k]) reader.malformed(w, fmt::format("is not an array of {} cells", cells[k]));
    t.counts.push_back(counts_from_json(counts[k], reader, w));
  }
  const nlohmann::json& checks = reader.member(j, "checks", where);
  if (!checks.is_array() || (checks.size() != 0 && checks.size() != blocks))
    reader.malformed(where + "/checks", fmt::format("is not an array of the checks of {} blocks", blocks));
  for (std::size_t b = 0; b < checks.size(); ++b)
    t.block_checks.push_back(checks_from_json(checks[b], reader, fmt::format("{}/checks/{}", where, b)));
  t.checks = battery::reduce_block_checks(t.block_checks);
  return t;
}

battery::Tally merge_tallies(const std::vector<const battery::Tally*>& all_parts) {
  if (all_parts.empty()) throw HistogramMergeError("nothing to merge");
  // A part of no block (a range split into more parts than it has blocks) adds nothing.
  std::vector<const battery::Tally*> parts;
  for (const battery::Tally* t : all_parts)
    if (t->samples > 0 || !t->block_checks.empty()) parts.push_back(t);
  if (parts.empty()) return *all_parts.front();
  battery::Tally merged = *parts.front();
  for (std::size_t i = 1; i < parts.size(); ++i) {
    const battery::Tally& t = *parts[i];
    if (t.has_pdf != merged.has_pdf || t.counts.size() != merged.counts.size() ||
        t.block_checks.empty() != merged.block_checks.empty())
      throw HistogramMergeError(fmt::format("part {}: its tally is not of the first part's kind", i + 1));
    merged.samples += t.samples;
    merged.failed += t.failed;
    merged.outside += t.outside;
    for (std::size_t k = 0; k < t.counts.size(); ++k) {
      if (t.counts[k].size() != merged.counts[k].size())
        throw HistogramMergeError(fmt::format("part {}: binning {} has {} cells, not {}", i + 1, k, t.counts[k].size(),
                                              merged.counts[k].size()));
      for (std::size_t c = 0; c < t.counts[k].size(); ++c) merged.counts[k][c] += t.counts[k][c];
    }
    merged.block_checks.insert(merged.block_checks.end(), t.block_checks.begin(), t.block_checks.end());
  }
  merged.checks = battery::reduce_block_checks(merged.block_checks);
  return merged;
}

}  // namespace microsim
