// measure: the HTML report of the BSDF battery (`check-bsdf --html`, Python `check_bsdf(html=...)`): its table
// and, per view, the residual maps of its cell tests (inline SVG; no external resource).
#pragma once

#include "measure/bsdf_battery.h"

#include <string>
#include <vector>

namespace microsim {

// title: the page's heading; facts: lines shown under it (the plugin, the claims, the options).
std::string battery_html(const BatteryReport& report, const std::string& title, const std::vector<std::string>& facts);

}  // namespace microsim
