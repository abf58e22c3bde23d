// experiment: the report's HTML pieces shared by the page (report.cpp) and the kinds' sections (each in its
// measurement_*.cpp, chosen through the registry: measurement.h kind_report). Internal to the module.
#pragma once

#include "experiment/report.h"
#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace microsim::experiment::html {

using nlohmann::json;
inline std::string esc(const std::string& s) { return svg::escape(s); }

inline std::string text_of(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number()) return report_number(v);
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  return v.is_null() ? "-" : v.dump();
}

// The member `key` of `j`, or std::invalid_argument naming it.
inline const json& member(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key))
    throw std::invalid_argument(fmt::format("experiment_report_html: the document has no '{}'", key));
  return j.at(key);
}

inline std::string row(const std::vector<std::string>& cells, const char* tag = "td") {
  std::string out = "<tr>";
  for (const std::string& c : cells) out += fmt::format("<{0}>{1}</{0}>", tag, c);
  return out + "</tr>\n";
}

// A table; an empty header: none.
inline std::string table(const std::vector<std::string>& header, const std::string& body) {
  std::vector<std::string> escaped;
  for (const std::string& h : header) escaped.push_back(esc(h));
  const std::string head = header.empty() ? "" : "<thead>" + row(escaped, "th") + "</thead>\n";
  return "<table>\n" + head + "<tbody>\n" + body + "</tbody></table>\n";
}

// A traced histogram's counts against what its probabilities expect (stats/figure.h), as a figure of the page;
// "" without probabilities. An estimate's value &plusmn; standard error. (report.cpp)
std::string histogram_figure(const TracedHistogram& h, const std::string& label, const std::string& expected);
std::string estimate_text(const json& e);

}  // namespace microsim::experiment::html
