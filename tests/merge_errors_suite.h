// A suite of merge-error tests: the parts of a run (and of other runs) are made once, in one directory, by
// the suite's SetUpTestSuite; each test checks that a merge of some of them is refused: exit 2, a message
// that names the problem, and no file written or changed.
#pragma once

#include "cli_helpers.h"

#include <gtest/gtest.h>

#include <string>

namespace microsim::test {

template <class Suite> class MergeErrorsSuite : public ::testing::Test {
protected:
  // The suite's directory (set by the suite's SetUpTestSuite, removed after its last test).
  static fs::path& dir() {
    static fs::path d;
    return d;
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }
  static void expect_refused(const std::string& args, const std::string& message) {
    const auto before = snapshot_files(dir());
    const CliRun r = run_cli(dir(), "merge " + args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_TRUE(snapshot_files(dir()) == before) << "merge " << args << " wrote a file";
  }
};

}  // namespace microsim::test
