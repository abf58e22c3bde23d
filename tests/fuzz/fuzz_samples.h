// The body of the two sample-file targets (fuzz_npy, fuzz_text): parse_direction_samples on the input
// under a file name whose extension picks the reader. Accepted input must give unit vectors or, for the
// sampler's failures (a non-finite value or the zero vector in the row), all-NaN vectors; rejected input
// a SampleFileError with a short message.
#pragma once

#include "fuzz_common.h"
#include "validate/sample_io.h"

#include <cmath>

namespace microsim::fuzz {

inline int fuzz_sample_file(const std::uint8_t* data, std::size_t size, const char* name) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    for (const auto& w : parse_direction_samples(bytes, name)) {
      const bool failure = w.array().isNaN().all();  // a row the sampler failed on, passed on as NaN
      if (!failure && !(std::abs(w.norm() - 1) < 1e-12)) finding("accepted a row that is neither unit nor a failure");
    }
  } catch (const SampleFileError& e) {
    check_message(e.what());
  }
  return 0;
}

}  // namespace microsim::fuzz
