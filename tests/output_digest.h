// Digests of command outputs for bit-identity tests (regression pins, shard/merge): a JSON report without
// the keys that measure the machine, EXR channels by FNV-1a of their float bits, and a comparison that
// names the first difference.
#pragma once

#include "cli_helpers.h"
#include "microgeom/exr_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <set>
#include <string>
#include <vector>

namespace microsim::test {

using nlohmann::json;

// Keys that measure the machine (times, rates, memory), name paths, or count threads.
inline bool is_volatile_key(const std::string& key) {
  static const std::set<std::string> named = {"threads", "output", "path", "command", "outputs", "markdown"};
  auto ends_with = [&](std::string_view suffix) { return key.ends_with(suffix); };
  return named.count(key) || ends_with("seconds") || ends_with("_bytes") || ends_with("_mib") ||
         ends_with("per_ray") || ends_with("per_second") || key.find("rss") != std::string::npos;
}

// The report without the keys that measure the machine.
inline json pinned_part(const json& j) {
  if (j.is_object()) {
    json out = json::object();
    for (auto it = j.begin(); it != j.end(); ++it)
      if (!is_volatile_key(it.key())) out[it.key()] = pinned_part(it.value());
    return out;
  }
  if (j.is_array()) {
    json out = json::array();
    for (const auto& v : j) out.push_back(pinned_part(v));
    return out;
  }
  return j;
}

inline std::string fnv1a_hex(const std::vector<float>& data) {
  std::uint64_t h = 1469598103934665603ull;
  for (float f : data) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    for (int k = 0; k < 4; ++k) {
      h ^= (bits >> (8 * k)) & 0xffu;
      h *= 1099511628211ull;
    }
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

inline json exr_digest(const fs::path& path) {
  const auto image = microgeom::read_exr(path);
  json d = {{"width", image.width}, {"height", image.height}, {"channels", json::object()}};
  for (const auto& c : image.channels) d["channels"][c.name] = fnv1a_hex(c.data);
  return d;
}

// Every value recorded in `want` must be in `got`, equal (numbers as doubles, exactly); keys added to the
// reports later are not pinned.
inline void expect_contains(const json& want, const json& got, const std::string& where) {
  if (want.is_object()) {
    ASSERT_TRUE(got.is_object()) << where << " is no longer an object";
    for (auto it = want.begin(); it != want.end(); ++it) {
      ASSERT_TRUE(got.contains(it.key())) << where << "/" << it.key() << " is missing";
      expect_contains(it.value(), got[it.key()], where + "/" + it.key());
    }
  } else if (want.is_array()) {
    ASSERT_TRUE(got.is_array() && got.size() == want.size()) << where << ": array size changed";
    for (std::size_t i = 0; i < want.size(); ++i) expect_contains(want[i], got[i], where + "/" + std::to_string(i));
  } else if (want.is_number()) {
    ASSERT_TRUE(got.is_number()) << where << " is no longer a number";
    EXPECT_EQ(want.get<double>(), got.get<double>()) << where;
  } else {
    EXPECT_EQ(want, got) << where;
  }
}

}  // namespace microsim::test
