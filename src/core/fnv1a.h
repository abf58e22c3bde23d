// core: FNV-1a, 64 bits (Fowler, Noll, Vo): identity checks of results (a spec, a shard's part, a traced
// histogram), not a security hash.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace microsim {

inline constexpr std::uint64_t kFnv1aOffset = 14695981039346656037ull;

// The hash `h` (kFnv1aOffset to start) continued over `bytes` bytes at `data`.
inline std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t k = 0; k < bytes; ++k) h = (h ^ p[k]) * 1099511628211ull;
  return h;
}

inline std::uint64_t fnv1a(std::string_view bytes) { return fnv1a(kFnv1aOffset, bytes.data(), bytes.size()); }

}  // namespace microsim
