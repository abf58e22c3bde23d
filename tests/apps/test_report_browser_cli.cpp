// The report in a real browser: `microsim run` on a tiny spec (seconds), then headless Chromium
// renders DIR/index.html from the file system with the network off: a screenshot of non-trivial size is
// produced, and the rendered page's text (--dump-dom) holds the measured values of results.json as the
// report prints them (experiment/report.h report_number). Negative control: a blank page's DOM does not.
// A run whose validation rejected (a dump of the talk listing's samples): the rendered page's first element is
// the verdict's headline (id "verdict", class "verdict fail": red), naming the rejected measurement.
// Skipped (GTEST_SKIP, with the reason) only when no `chromium` is installed; CI installs it (scripts/setup.sh).
#include "cli_helpers.h"
#include "sample_dumps.h"

#include "experiment/report.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_report_browser_cli {

namespace {

namespace fs = std::filesystem;
using microsim::experiment::report_number;
using microsim::test::run_cli;
using microsim::test::scratch_dir;
using microsim::test::slurp;

// The chromium executable on PATH, or "".
std::string find_chromium() {
  const char* path = std::getenv("PATH");
  std::string dirs = path != nullptr ? path : "/usr/bin:/bin";
  for (std::size_t start = 0; start <= dirs.size();) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const fs::path candidate = fs::path(dirs.substr(start, end - start)) / "chromium";
    if (!candidate.parent_path().empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    start = end + 1;
  }
  return "";
}

// Runs headless chromium with ARGS on URL (a fresh profile, no network, no background services); its stdout
// goes to `out`. Returns the exit code.
int chromium(const std::string& binary, const fs::path& work, const std::string& args, const std::string& url,
             const fs::path& out) {
  const fs::path profile = work / "profile";
  fs::remove_all(profile);
  fs::create_directories(profile);
  const std::string cmd = "cd '" + work.string() + "' && timeout 180 '" + binary +
                          "' --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
                          "--disable-background-networking --disable-component-update --disable-sync "
                          "--user-data-dir='" + profile.string() + "' " + args + " '" + url + "' > '" +
                          out.string() + "' 2> '" + (work / "chromium.stderr").string() + "'";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The PNG's width and height (its IHDR chunk), or 0 x 0.
std::pair<unsigned, unsigned> png_size(const fs::path& png) {
  const std::string bytes = slurp(png);
  if (bytes.size() < 24 || bytes.compare(1, 3, "PNG") != 0) return {0, 0};
  const auto be32 = [&](std::size_t at) {
    unsigned v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<unsigned char>(bytes[at + i]);
    return v;
  };
  return {be32(16), be32(20)};
}

// The measured values the rendered page must show: per measurement the achieved error, and the table's
// E_avg and the VNDF's measured TV.
std::vector<std::string> measured_values(const nlohmann::json& results) {
  std::vector<std::string> values;
  for (const auto& m : results["results"]["measurements"]) {
    values.push_back(report_number(m["achieved"]));
    const auto& v = m["values"];
    if (v.contains("quantities"))
      for (const auto& e : v["quantities"]["E1"]["average"]) values.push_back(report_number(e));
    if (v.contains("total_variation")) values.push_back(report_number(v["total_variation"]));
  }
  return values;
}

TEST(ReportBrowser, ChromiumRendersTheReportWithItsMeasuredValues) {
  const std::string binary = find_chromium();
  if (binary.empty())
    GTEST_SKIP() << "chromium is not installed (Debian package 'chromium', installed by scripts/setup.sh): "
                    "the report's browser test cannot run here";
  const fs::path dir = scratch_dir("report", "browser");
  std::ofstream(dir / "tiny.toml")
      << "[[material]]\nname = \"m\"\nalphas = [0.3, 0.7]\ntype = \"mirror\"\n[[quantity]]\nkind = \"albedo\"\n"
         "material = \"m\"\nmus = 3\ntarget_relative_error = 0.001\n[[quantity]]\nkind = \"vndf\"\nmaterial = \"m\"\n"
         "theta = [30]\nrows = 7\ntarget_tv = 0.1\n";
  const auto run = run_cli(dir, "run tiny.toml --out out");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string url = "file://" + (dir / "out" / "index.html").string();
  ASSERT_EQ(chromium(binary, dir, "--window-size=1280,1600 --screenshot=" + (dir / "shot.png").string(), url, dir / "shot.out"), 0)
      << slurp(dir / "chromium.stderr");
  const auto [width, height] = png_size(dir / "shot.png");
  EXPECT_EQ(width, 1280u);
  EXPECT_EQ(height, 1600u);
  EXPECT_GT(fs::file_size(dir / "shot.png"), 20000u);  // a rendered page, not a blank one
  ASSERT_EQ(chromium(binary, dir, "--dump-dom", url, dir / "dom.html"), 0) << slurp(dir / "chromium.stderr");
  const std::string dom = slurp(dir / "dom.html");
  const std::vector<std::string> values = measured_values(nlohmann::json::parse(slurp(dir / "out" / "results.json")));
  ASSERT_GE(values.size(), 7u);  // 3 achieved, 2 E_avg, 2 TV
  for (const std::string& v : values) EXPECT_NE(dom.find(v), std::string::npos) << v;
  EXPECT_NE(dom.find("<svg"), std::string::npos);
  // Negative control: the same check on a blank page fails.
  ASSERT_EQ(chromium(binary, dir, "--dump-dom", "about:blank", dir / "blank.html"), 0);
  EXPECT_EQ(slurp(dir / "blank.html").find(values.front()), std::string::npos);
  fs::remove_all(dir);
}

// The first element of the rendered body (from its '<' to the end of its text), or "".
std::string first_body_element(const std::string& dom) {
  const std::size_t body = dom.find("<body");
  if (body == std::string::npos) return "";
  const std::size_t start = dom.find('<', dom.find('>', body) + 1);
  const std::size_t end = dom.find("</", start);
  return start == std::string::npos || end == std::string::npos ? "" : dom.substr(start, end - start);
}

TEST(ReportBrowser, ChromiumShowsARejectedRunsVerdictFirst) {
  const std::string binary = find_chromium();
  if (binary.empty())
    GTEST_SKIP() << "chromium is not installed (Debian package 'chromium', installed by scripts/setup.sh): "
                    "the report's browser test cannot run here";
  const fs::path dir = scratch_dir("report", "browser_verdict");
  microsim::test::write_sampler_dump(dir / "talk.npy", "heitz2018-talk", 0.3, 40, 50000);
  std::ofstream(dir / "talk.toml")
      << "[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n[[quantity]]\nkind = \"validation\"\n"
         "material = \"m\"\ndump = \"talk.npy\"\ntheta = [40]\nrows = 7\ndetect_tv = 0.05\n";
  const auto run = run_cli(dir, "run talk.toml --out out");
  ASSERT_EQ(run.exit_code, 1) << run.err;
  const nlohmann::json results = nlohmann::json::parse(slurp(dir / "out" / "results.json"))["results"];
  ASSERT_EQ(results["rejected"].size(), 1u);
  const std::string url = "file://" + (dir / "out" / "index.html").string();
  ASSERT_EQ(chromium(binary, dir, "--dump-dom", url, dir / "dom.html"), 0) << slurp(dir / "chromium.stderr");
  const std::string first = first_body_element(slurp(dir / "dom.html"));
  EXPECT_EQ(first.rfind("<p id=\"verdict\" class=\"verdict fail\">", 0), 0u) << first;
  EXPECT_NE(first.find("Verdict: FAIL"), std::string::npos) << first;
  EXPECT_NE(first.find(results["rejected"][0].get<std::string>()), std::string::npos) << first;
  // Negative control: the same reading of a blank page finds no headline.
  ASSERT_EQ(chromium(binary, dir, "--dump-dom", "about:blank", dir / "blank.html"), 0);
  EXPECT_EQ(first_body_element(slurp(dir / "blank.html")).find("verdict"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_report_browser_cli
