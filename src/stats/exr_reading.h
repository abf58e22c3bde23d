// stats: microgeom::read_exr for the file readers of stats (histogram_io, scatter_io): out of memory passes
// unchanged, every other failure (no such file, not an EXR, a header claiming too much) becomes the reader's
// own error type, with the EXR reader's message (it names the path).
#pragma once

#include "microgeom/exr_io.h"

#include <exception>
#include <filesystem>
#include <new>

namespace microsim {

template <class Error> microgeom::ExrImage read_exr_or(const std::filesystem::path& path) {
  try {
    return microgeom::read_exr(path);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(e.what());
  }
}

}  // namespace microsim
