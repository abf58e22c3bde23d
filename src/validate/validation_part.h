// validate: a validation in parts. A validation draws its samples in blocks of kSampleBlock (validate.h):
// a shard (ValidationOptions::blocks) draws and tallies a range of them, without the cubature of the
// reference, and records the tally exactly: the integer counts of every cell, and each block's checks of
// the returned pdf (their reduction, a Welford/Chan combination, is not associative in floating point, so
// a merge reduces the blocks' checks again, in block order, from the first). The merged tally of all the
// shards is the single run's, bit for bit, and the report computed from it (report_drawn_samples, the
// same code validate_sampler runs) is the single run's report.
#pragma once

#include "stats/part_json.h"
#include "validate/battery.h"
#include "validate/compare.h"

#include <nlohmann/json.hpp>

#include <vector>

namespace microsim {

// The tally of the samples validate_sampler draws from `sampler` for `reference` (its blocks
// options.blocks, or all): counts in the reference's binnings, and the checks of its claimed pdf. The
// reference needs no bin probabilities (claimed_reference_bins). Throws Cancelled when options.run is.
battery::Tally tally_drawn_samples(const SamplerInfo& sampler, const ReferenceDistribution& reference,
                                   const ValidationOptions& options);
// validate_sampler's report from the tally of all its samples, against the integrated `reference`.
ValidationReport report_drawn_samples(const SamplerInfo& sampler, const ReferenceDistribution& reference,
                                      const battery::Tally& tally, const ValidationOptions& options);

// The same two steps for the comparison with a traced histogram (compare_sampler_to_trace): the tally in
// the histogram's binnings, and the two-sample report against its counts. The tally throws
// std::invalid_argument for a sampler of reflected directions or a histogram of another configuration, and
// InsufficientData when options.samples (or the histogram's hits) are too few for the two-sample tests.
battery::Tally tally_drawn_samples_for_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                             const ValidationOptions& options, const TracedHistogram& traced);
ValidationReport report_drawn_samples_against_trace(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                    const Vec3<double>& wi, const battery::Tally& tally,
                                                    const ValidationOptions& options, const TracedHistogram& traced);

// A tally as JSON: {"samples", "failed", "outside", "has_pdf", "counts": [[per cell], ...], "checks":
// [per block {"n", "mean", "m2", "worst", "worst_index", "outliers", "direction", "returned"}]}, counts as
// integers and every real of the checks exactly (exact_real_json).
nlohmann::json tally_json(const battery::Tally& tally);
// Reads a tally of `blocks` blocks in binnings of `cells` cells each (bins and the remainder cell).
// Throws HistogramMergeError (reader's form) naming what is missing or malformed.
battery::Tally tally_from_json(const nlohmann::json& j, const std::vector<std::size_t>& cells, std::uint64_t blocks,
                               const PartReader& reader, const std::string& where);
// The tallies of consecutive block ranges of one validation, given in block order, as one: counts added,
// the blocks' checks concatenated and reduced again from the first. Throws HistogramMergeError when the
// tallies are of different binnings or one has returned pdfs and another not.
battery::Tally merge_tallies(const std::vector<const battery::Tally*>& in_block_order);

}  // namespace microsim
