// libFuzzer target: the .npy reader (microsim::parse_direction_samples on a name ending in .npy).
#include "fuzz_samples.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return microsim::fuzz::fuzz_sample_file(data, size, "fuzz.npy");
}
