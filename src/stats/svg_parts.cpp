// The pieces of the SVG figures (svg_parts.h).
#include "stats/svg_parts.h"

namespace microsim::svg {
namespace {
constexpr double kDegree = 3.14159265358979323846 / 180;
}  // namespace

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// theta (degrees) of the parameter-space z at a row edge k in [0, rows].
double edge_theta_deg(const DirectionBinning& b, int k) {
  const double z = b.z_max() - (b.z_max() - b.z_min()) * k / b.rows();
  return std::acos(std::clamp(z, -1.0, 1.0)) / kDegree;
}

std::string axes(const Panel& p, const DirectionBinning& b, const std::string& title) {
  std::string out;
  out += fmt::format(R"(<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#444" stroke-width="0.8"/>)",
                     p.x, p.y, p.width(), p.height());
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="13">{}</text>)", p.x + p.width() / 2,
                     p.y - 8, escape(title));
  for (int deg = 0; deg <= 360; deg += 90) {
    const double x = p.x + p.width() * deg / 360.0;
    out += fmt::format(R"(<line x1="{0}" x2="{0}" y1="{1}" y2="{2}" stroke="#444"/>)", x, p.y + p.height(),
                       p.y + p.height() + 4);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">{}</text>)", x,
                       p.y + p.height() + 15, deg);
  }
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">phi (deg)</text>)",
                     p.x + p.width() / 2, p.y + p.height() + 27);
  // theta ticks every 30 degrees inside the parameter space's z range (rows are equal in z, not theta).
  const double theta_top = edge_theta_deg(b, 0), theta_bottom = edge_theta_deg(b, b.rows());
  double last_y = -1e9;
  for (int deg = 0; deg <= 180; deg += 30) {
    if (deg < theta_top - 1e-9 || deg > theta_bottom + 1e-9) continue;
    const double z = std::cos(deg * kDegree);
    const double y = p.y + p.height() * (b.z_max() - z) / (b.z_max() - b.z_min());
    if (y - last_y < 11) continue;  // labels would overlap (near the poles, z changes slowly)
    last_y = y;
    out += fmt::format(R"(<line x1="{0}" x2="{1}" y1="{2}" y2="{2}" stroke="#444"/>)", p.x - 4, p.x, y);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" font-size="10">{}</text>)", p.x - 6, y + 3.5, deg);
  }
  return out;
}

std::string colorbar(double x, double y, double width, const std::string& gradient_id, const std::string& low,
                     const std::string& high, const std::string& label) {
  std::string out = fmt::format(R"~(<rect x="{}" y="{}" width="{}" height="8" fill="url(#{})" stroke="#444" stroke-width="0.5"/>)~",
                                x, y, width, gradient_id);
  out += fmt::format(R"(<text x="{}" y="{}" font-size="10">{}</text>)", x, y + 19, escape(low));
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" font-size="10">{}</text>)", x + width, y + 19,
                     escape(high));
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">{}</text>)", x + width / 2, y + 19,
                     escape(label));
  return out;
}

std::vector<std::string> subtitle_lines(const std::string& subtitle) {
  std::vector<std::string> lines;
  for (std::size_t start = 0;;) {
    const std::size_t end = subtitle.find('\n', start);
    lines.push_back(subtitle.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return lines;
}

std::string document_header(double width, double height, double margin, const std::string& title,
                            const std::vector<std::string>& lines) {
  std::string svg = fmt::format(
      R"(<svg xmlns="http://www.w3.org/2000/svg" width="{0}" height="{1}" viewBox="0 0 {0} {1}" font-family="sans-serif">)"
      "\n",
      std::ceil(width), std::ceil(height));
  svg += "<defs>" + gradient("sequential", kSequential) + gradient("diverging", kDiverging) + "</defs>\n";
  svg += fmt::format(R"(<rect width="100%" height="100%" fill="white"/>)"
                     R"(<text x="{}" y="22" font-size="15" font-weight="bold">{}</text>)",
                     margin, escape(title));
  for (std::size_t i = 0; i < lines.size(); ++i)
    svg += fmt::format(R"(<text x="{}" y="{}" font-size="12">{}</text>)", margin, 42 + 17 * i, escape(lines[i]));
  return svg + "\n";
}

}  // namespace microsim::svg
