// The HTML report of the BSDF battery (bsdf_battery_html.h).
#include "measure/bsdf_battery_html.h"

#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace microsim {
namespace {

constexpr const char* kStyle = R"(<style>
body{font-family:sans-serif;max-width:1400px;margin:1.5em auto;padding:0 1em;color:#222;line-height:1.4}
table{border-collapse:collapse;margin:0.6em 0 1.2em;font-size:13px}
th,td{border:1px solid #bbb;padding:3px 7px;text-align:left;vertical-align:top}
.pass{color:#1a7f37}.fail{color:#b42318;font-weight:bold}
figure{display:inline-block;margin:0.4em}
</style>
)";

std::string esc(const std::string& s) { return svg::escape(s); }

// One residual map: cells of the sphere (z from +1 at the top to -1 at the bottom, phi from 0 left to 360 deg
// right), coloured by z on the diverging scale clamped to [-4, 4].
std::string residual_svg(const BatteryResiduals& r) {
  constexpr double cell = 14, left = 40, top = 28;
  const double w = left + r.cols * cell + 10, h = top + r.rows * cell + 58;
  std::string out = fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">)", w, h, w, h);
  out += fmt::format(R"(<defs>{}</defs><rect width="100%" height="100%" fill="white"/>)", svg::gradient("diverging", svg::kDiverging));
  out += fmt::format(R"(<text x="{}" y="16" font-size="13">{} {}</text>)", left, esc(r.test), esc(r.view));
  for (int row = 0; row < r.rows; ++row)
    for (int col = 0; col < r.cols; ++col) {
      const double z = r.z[std::size_t((r.rows - 1 - row) * r.cols + col)];
      const std::string fill = !std::isnan(z) ? svg::color_at(svg::kDiverging, (std::clamp(z, -4.0, 4.0) + 4) / 8) : "#dddddd";
      out += fmt::format(R"(<rect x="{}" y="{}" width="{}" height="{}" fill="{}"/>)", left + col * cell, top + row * cell, cell,
                         cell, fill);
    }
  out += fmt::format(R"(<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#444"/>)", left, top, r.cols * cell,
                     r.rows * cell);
  out += fmt::format(R"(<text x="4" y="{}" font-size="11">z=1</text><text x="2" y="{}" font-size="11">z=-1</text>)",
                     top + 10, top + r.rows * cell);
  out += fmt::format(R"(<text x="{}" y="{}" font-size="11">phi 0 .. 360 deg</text>)", left, top + r.rows * cell + 14);
  out += svg::colorbar(left, top + r.rows * cell + 24, r.cols * cell, "diverging", "-4", "4", "residual z");
  return out + "</svg>";
}

std::string lines_table(const BatteryReport& r) {
  std::string out = "<table>\n<thead><tr><th>test</th><th>view</th><th>p</th><th>verdict</th><th>detail</th></tr></thead>\n<tbody>\n";
  for (const BatteryLine& l : r.lines)
    out += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td><td>{}</td></tr>\n", esc(l.test),
                       esc(l.view), l.p < 0 ? "-" : fmt::format("{:.3g}", l.p), l.passed ? "pass" : "fail",
                       l.verdict_word(), esc(l.detail));
  return out + "</tbody></table>\n";
}

}  // namespace

std::string battery_html(const BatteryReport& report, const std::string& title, const std::vector<std::string>& facts) {
  std::string page = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  page += fmt::format("<title>{}</title>\n", esc(title)) + kStyle + "</head>\n<body>\n";
  page += fmt::format("<h1>{}</h1>\n<p class=\"{}\">{}</p>\n<ul>\n", esc(title), report.passed ? "pass" : "fail",
                      report.passed ? "passed: every test" : "REJECTED");
  for (const std::string& f : facts) page += "<li>" + esc(f) + "</li>\n";
  if (!report.convention.empty()) page += "<li>convention: " + esc(report.convention) + "</li>\n";
  page += "</ul>\n<h2>Tests</h2>\n" + lines_table(report);
  page += "<h2>Residuals per cell</h2>\n<p>Each map is the sphere's equal-area cells (rows: z = cos theta of wo from +1 "
          "at the top to -1 at the bottom; columns: phi). The residual of a cell is (a - lambda b) / sqrt(var a + "
          "lambda^2 var b), a the samples' histogram (weighted for the integral test, counts for the density test), b "
          "the integral of eval() (or pdf()) over the cell, lambda = sum a / sum b; grey: both empty.</p>\n";
  for (const BatteryResiduals& r : report.residuals) page += "<figure>" + residual_svg(r) + "</figure>\n";
  return page + "</body>\n</html>\n";
}

}  // namespace microsim
