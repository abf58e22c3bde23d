// stats: a partial result as JSON, the one form in which `microsim merge` receives the parts of a run
// (trace vndf, scatter, trace masking, validate, stability; the experiment's ranks and shards too): its
// provenance, the run's parameters, and numbers that round-trip exactly.
//
//   {"provenance": {"producer": "...", "parameters": {...}, "seed": S, "blocks": [B, E], "total_blocks": T},
//    ... the producer's own members ...}
//
// The parameters are everything that defines the run but the seed and the blocks; parts of one run have
// equal parameters (compared member by member, so a message names the first that differs). A real that
// must round-trip bit for bit (a sum, a mean, a worst case that may be infinite) is written as the 16 hex
// digits of its IEEE-754 bits (exact_real_json); an exact sum (core/exact_sum.h) as its two 64-bit halves
// (exact_sum_json); counts are JSON integers. JSON numbers otherwise are for what a reader may want to read.
#pragma once

#include "stats/histogram.h"
#include "stats/scatter_histogram.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace microsim {

// The provenance member of a part; `provenance.measurement` is not written (it is parameters.dump()).
nlohmann::json provenance_json(const Provenance& provenance, const nlohmann::json& parameters);

// The producer a JSON report names in its provenance, or "" when it has none (not a part).
std::string producer_of(const nlohmann::json& report);

// The 16 hex digits of the bits of x: exact for every double (infinities, NaN, -0 included).
std::string exact_real_json(double x);

// An exact sum as [HIGH, LOW], the two 64-bit halves of its 128-bit fixed-point value: exact.
nlohmann::json exact_sum_json(const ExactSum& s);

// Reads the members of a part of one producer. Every error is a HistogramMergeError that reads
// "not a PRODUCER part: WHERE/KEY is missing" (or "... is not a count", ...), WHERE the member's path.
class PartReader {
public:
  explicit PartReader(std::string producer) : producer_(std::move(producer)) {}

  [[noreturn]] void malformed(const std::string& where, const std::string& what) const;
  const nlohmann::json& member(const nlohmann::json& j, const char* key, const std::string& where) const;
  std::uint64_t count(const nlohmann::json& j, const char* key, const std::string& where) const;
  double real(const nlohmann::json& j, const char* key, const std::string& where) const;  // a JSON number
  std::string text(const nlohmann::json& j, const char* key, const std::string& where) const;
  bool flag(const nlohmann::json& j, const char* key, const std::string& where) const;
  double exact_real(const nlohmann::json& v, const std::string& where) const;  // exact_real_json's form
  double exact_real(const nlohmann::json& j, const char* key, const std::string& where) const;
  // An array member of exactly `size` elements.
  const nlohmann::json& array(const nlohmann::json& j, const char* key, std::size_t size, const std::string& where) const;
  // exact_sum_json's form: [HIGH, LOW], two counts, HIGH below 2^63 (a sum of non-negative terms).
  ExactSum exact_sum(const nlohmann::json& v, const std::string& where) const;

  // The provenance of a part: producer (must be this reader's), parameters (an object), seed, blocks
  // (a range within total_blocks). provenance.measurement = parameters.dump().
  Provenance provenance(const nlohmann::json& report, nlohmann::json& parameters) const;

private:
  template <class T>
  T typed(const nlohmann::json& j, const char* key, const std::string& where,
          bool (nlohmann::json::*is_t)() const noexcept, const char* what) const;
  std::string producer_;
};

// The exact sums of a scattering histogram: {"paths": N, "channels": [per channel {"orders": [per order bin
// {"w": [per bin], "w2": [per bin], "unbinned": [w, w2]}], "unfinished": [w, w2], "lost": [w, w2]}]}, every
// sum in exact_sum_json's form.
nlohmann::json scatter_sums_json(const ScatterHistogram& histogram);
// Adds sums of that form (member `where` of a part read by `reader`) to `sum`, a histogram of their binning
// and channels: the histogram they were written from when `sum` was empty. HistogramMergeError names a
// member missing or malformed, or sizes other than sum's.
void add_scatter_sums(ScatterHistogram& sum, const nlohmann::json& sums, const PartReader& reader,
                      const std::string& where);

// Throws HistogramMergeError unless part `name` has the first part's parameters: "NAME is not part of the
// same run: KEY is 'VALUE' there, 'VALUE' in the first part" for the first parameter that differs.
void check_same_parameters(const nlohmann::json& first, const nlohmann::json& other, const std::string& name);

// The parts' provenances (of one producer) as one run: every parameter and the seed equal, the block
// ranges joining into [0, total_blocks) without a gap or a repeat (HistogramMergeError naming them).
// Returns the order of the parts by their first block, the order in which their results are reduced.
std::vector<std::size_t> check_parts_of_one_run(const std::vector<Provenance>& provenances,
                                                const std::vector<nlohmann::json>& parameters);
// The same for parts that carry their `provenance` and `parameters` members (a validation's, an albedo table's).
template <class Part> std::vector<std::size_t> check_parts_of_one_run(const std::vector<Part>& parts) {
  std::vector<Provenance> provenances;
  std::vector<nlohmann::json> parameters;
  for (const Part& p : parts) {
    provenances.push_back(p.provenance);
    parameters.push_back(p.parameters);
  }
  return check_parts_of_one_run(provenances, parameters);
}

}  // namespace microsim
