// libFuzzer target: the .npy reader (microsim::parse_direction_samples on a name ending in .npy).
// Accepted input must give unit vectors; rejected input a SampleFileError with a short message.
#include "fuzz_common.h"
#include "microsim/sample_io.h"

#include <cmath>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    for (const auto& w : microsim::parse_direction_samples(bytes, "fuzz.npy"))
      if (!(std::abs(w.norm() - 1) < 1e-12)) microsim::fuzz::finding("accepted a row that is not a unit vector");
  } catch (const microsim::SampleFileError& e) {
    microsim::fuzz::check_message(e.what());
  }
  return 0;
}
