// libFuzzer target: the scatter EXR reader (microgeom::read_exr_memory, then microsim::scatter_from_exr).
// Accepted input must satisfy the reader's promises (one sum per bin, order and channel; expectations finite
// and >= 0; the block range inside the run; 1 to 64 channels); rejected input a std::runtime_error with a
// short message.
#include "fuzz_common.h"
#include "microgeom/exr_io.h"
#include "microfacet/material.h"
#include "stats/scatter_io.h"

#include <cmath>
#include <new>
#include <span>

namespace {
void check(const microsim::ScatterFile& f) {
  if (f.kind == microsim::ScatterFileKind::histogram) {
    const microsim::ScatterHistogram& h = f.histogram;
    if (h.channels() < 1 || h.channels() > microsim::Material::kMaxChannels) microsim::fuzz::finding("channel count");
    for (int c = 0; c < h.channels(); ++c)
      for (int k = 0; k < microsim::kScatterOrderBins; ++k)
        if (h.histogram(c, k).size() != h.bins()) microsim::fuzz::finding("a sum per bin");
    const microsim::Provenance& p = h.provenance;
    if (p.blocks.begin > p.blocks.end || p.blocks.end > p.total_blocks) microsim::fuzz::finding("blocks outside the run");
    return;
  }
  const microsim::ScatterExpectation& e = f.expectation;
  if (e.order1.size() != e.channel_names.size()) microsim::fuzz::finding("a lobe per channel");
  for (const auto& lobe : e.order1) {
    if (lobe.size() != e.bins()) microsim::fuzz::finding("an expectation per bin");
    for (double v : lobe)
      if (!std::isfinite(v) || v < 0) microsim::fuzz::finding("an expectation that is not finite and >= 0");
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const char> bytes(reinterpret_cast<const char*>(data), size);
  try {
    const microgeom::ExrImage image = microgeom::read_exr_memory(bytes, "fuzz.exr", microsim::fuzz::kFuzzExrDecodedBytes);
    check(microsim::scatter_from_exr(image, "fuzz.exr"));
  } catch (const std::bad_alloc&) {
    microsim::fuzz::finding("std::bad_alloc: an allocation the size checks should have refused");
  } catch (const std::exception& e) {
    microsim::fuzz::check_message(e.what());
  }
  return 0;
}
