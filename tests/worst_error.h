// Tracks the worst error of one identity over a test's configurations and reports it when the test
// ends: printed, and recorded as a GoogleTest property ("worst_error_<name>") for the docs' tables.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace microsim::test {

struct WorstError {
  std::string name;
  double worst = 0;
  std::string where{};
  void add(double err, const std::string& w) {
    if (!(err <= worst)) {  // NaN counts as worst
      worst = err;
      where = w;
    }
  }
  ~WorstError() {
    std::printf("[ identity ] %-50s worst |error| = %.3g at %s\n", name.c_str(), worst, where.c_str());
    char value[32];
    std::snprintf(value, sizeof value, "%.3g", worst);
    ::testing::Test::RecordProperty("worst_error_" + name, value);
  }
};

}  // namespace microsim::test
