// The `microsim` binary the tests run: $MICROSIM_BINARY when it is set (the sanitizer gate runs the Release
// build's command-line tests against its instrumented binary, scripts/sanitize.sh), else the one built
// beside the tests (MICROSIM_BUILT_BINARY, set by CMakeLists.txt).
#pragma once

#include <cstdlib>
#include <string>

namespace microsim::test {

inline std::string microsim_binary() {
  const char* given = std::getenv("MICROSIM_BINARY");
  return given && *given ? std::string(given) : std::string(MICROSIM_BUILT_BINARY);
}

// Whether that binary is built with AddressSanitizer (its peak memory is then not the program's own):
// this test binary is, or $MICROSIM_BINARY_INSTRUMENTED is set (the sanitizer gate sets it).
inline bool microsim_binary_is_instrumented() {
#if defined(__SANITIZE_ADDRESS__)
  return true;
#else
  const char* flag = std::getenv("MICROSIM_BINARY_INSTRUMENTED");
  return flag && *flag && std::string(flag) != "0";
#endif
}

}  // namespace microsim::test
