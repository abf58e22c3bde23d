// libFuzzer target: the heightmap EXR reader (microgeom::read_exr_memory, then microgeom::heightfield_from_exr
// with the tile size from the file). Accepted input must be a square field of finite heights with a finite
// positive tile size and finite slopes; rejected input a std::exception with a short message.
#include "fuzz_common.h"
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"

#include <cmath>
#include <new>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const char> bytes(reinterpret_cast<const char*>(data), size);
  try {
    microgeom::ExrImage image = microgeom::read_exr_memory(bytes, "fuzz.exr", microsim::fuzz::kFuzzExrDecodedBytes);
    const microgeom::Heightfield f = microgeom::heightfield_from_exr(std::move(image), "fuzz.exr");
    if (!(f.resolution() >= 2 && std::isfinite(f.tile_size()) && f.tile_size() > 0))
      microsim::fuzz::finding("accepted a bad resolution or tile size");
    for (int j = 0; j < f.resolution(); ++j)
      for (int i = 0; i < f.resolution(); ++i)
        if (!f.triangle_normal(i, j, 0).allFinite() || !f.triangle_normal(i, j, 1).allFinite())
          microsim::fuzz::finding("accepted a field with a non-finite normal");
  } catch (const std::bad_alloc&) {
    microsim::fuzz::finding("std::bad_alloc: an allocation the size checks should have refused");
  } catch (const std::exception& e) {
    microsim::fuzz::check_message(e.what());
  }
  return 0;
}
