// libFuzzer target: the histogram EXR reader (microgeom::read_exr_memory, then microsim::histogram_from_exr).
// Accepted input must satisfy the reader's promises (counts add up to at most hits <= rays, one count per
// bin, probabilities finite); rejected input a std::runtime_error with a short message.
#include "fuzz_common.h"
#include "microgeom/exr_io.h"
#include "stats/histogram_io.h"

#include <cmath>
#include <new>
#include <span>

namespace {
void check(const microsim::TracedHistogram& h) {
  if (h.hits > h.rays) microsim::fuzz::finding("hits > rays accepted");
  if (h.binnings.empty() || h.counts.size() != h.binnings.size()) microsim::fuzz::finding("binnings/counts mismatch");
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    if (h.counts[k].size() != std::size_t(h.binnings[k].size())) microsim::fuzz::finding("a count per bin");
    std::uint64_t total = 0;
    for (std::uint64_t c : h.counts[k]) total += c;
    if (total > h.hits) microsim::fuzz::finding("counts add up to more than hits");
    for (double p : h.probability[k])
      if (!std::isfinite(p) || p < 0) microsim::fuzz::finding("a probability that is not finite and >= 0");
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const char> bytes(reinterpret_cast<const char*>(data), size);
  try {
    const microgeom::ExrImage image =
        microgeom::read_exr_memory(bytes, "fuzz.exr", microsim::fuzz::kFuzzExrDecodedBytes);
    check(microsim::histogram_from_exr(image, "fuzz.exr"));
  } catch (const std::bad_alloc&) {
    microsim::fuzz::finding("std::bad_alloc: an allocation the size checks should have refused");
  } catch (const std::exception& e) {
    microsim::fuzz::check_message(e.what());
  }
  return 0;
}
