// microsim fuzz targets: what every target checks besides "no crash, no leak, no sanitizer report".
#pragma once

#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

namespace microsim::fuzz {

// Error messages quote at most a short excerpt of the input: a longer one is a finding.
inline constexpr std::size_t kMaxMessageBytes = 1000;

// The EXR targets decode at most this much float data per input: the reader's own limit
// (kMaxExrDecodedBytes, 2 GiB) is for real files; fuzzing needs many executions per second.
inline constexpr std::uint64_t kFuzzExrDecodedBytes = std::uint64_t(16) << 20;

inline void check_message(std::string_view message) {
  if (message.size() > kMaxMessageBytes) {
    std::fprintf(stderr, "error message of %zu bytes (more than %zu): %.300s...\n", message.size(),
                 kMaxMessageBytes, std::string(message).c_str());
    std::abort();
  }
}

[[noreturn]] inline void finding(const char* what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what);
  std::abort();
}

}  // namespace microsim::fuzz
