#include "microfacet/roughness.h"

#include <fmt/core.h>

#include <algorithm>

namespace microsim {
namespace {
// The range check of check_supported_alpha, naming the value as `shown` (the token, or the number).
void check_alpha_value(std::string_view what, std::string_view shown, double a) {
  const Interval supported{kMinAlpha, kMaxSupportedAlpha};
  if (!supported.contains(a))
    throw ParseError(fmt::format("{} {}: outside the supported roughness range {} (docs/reference/conventions.md)", what, shown,
                                 supported.to_string()));
}

void check_anisotropy(std::string_view what, double ax, double ay) {
  // Relative slack of a few ulps: 1e-4 and 0.1 (= 1e-4 * 1000 rounded) are the documented 1:1000.
  const double ratio = std::max(ax, ay) / std::min(ax, ay);
  if (ratio > kMaxSupportedAnisotropy * (1 + 1e-12))
    throw ParseError(fmt::format("{} {:g},{:g}: anisotropy 1:{:.4g} beyond the supported 1:{:g} (docs/reference/conventions.md)",
                                 what, ax, ay, ratio, kMaxSupportedAnisotropy));
}
}  // namespace

void check_supported_alpha(std::string_view what, double ax, double ay) {
  for (double a : {ax, ay}) check_alpha_value(what, fmt::format("{:g}", a), a);
  check_anisotropy(what, ax, ay);
}

std::pair<double, double> parse_alpha(std::string_view what, std::string_view text) {
  const std::vector<std::string_view> items = split_list(what, text, 1, 2);
  double a[2] = {0, 0};
  for (std::size_t k = 0; k < items.size(); ++k) {
    const std::string name = items.size() == 1 ? std::string(what) : list_item_name(what, text, k);
    a[k] = parse_double(name, items[k]);
    check_alpha_value(name, quote_excerpt(items[k]), a[k]);
  }
  const double ax = a[0], ay = items.size() == 2 ? a[1] : a[0];
  check_anisotropy(what, ax, ay);
  return {ax, ay};
}

}  // namespace microsim
