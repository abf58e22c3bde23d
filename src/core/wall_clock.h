// core: wall-clock time of a step, as the reports state it (steady clock: never set back).
#pragma once

#include <chrono>

namespace microsim {

// Seconds of wall-clock time since `start` (a steady_clock reading).
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace microsim
