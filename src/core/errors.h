// core: the error types that decide a command's exit code. A library throws; the command line maps:
//   std::invalid_argument, std::runtime_error (a file that cannot be read, a value out of range) -> bad input (2)
//   InternalError (an Embree failure, a broken invariant), std::bad_alloc                          -> internal (3)
//   Cancelled (core/run_control.h: a step with no partial result, cancelled)                       -> interrupted (130)
#pragma once

#include <stdexcept>

namespace microsim {

// A failure that is not the input's fault: the ray tracer failed, or an invariant of the code broke.
struct InternalError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace microsim
