#include "microfacet/material.h"

#include "core/parse.h"
#include "microfacet/bsdf.h"

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::vector<std::string> default_channel_names(std::size_t n) {
  std::vector<std::string> names;
  for (std::size_t c = 0; c < n; ++c) names.push_back(fmt::format("c{}", c));
  return names;
}

// The part after "KIND:", or empty when there is none.
std::string_view argument_of(std::string_view text, std::string_view kind) {
  return text.size() > kind.size() ? text.substr(kind.size() + 1) : std::string_view{};
}

bool has_kind(std::string_view text, std::string_view kind) {
  return text == kind || (text.size() > kind.size() && text.substr(0, kind.size()) == kind && text[kind.size()] == ':');
}

// "ETA,K;ETA,K..." -> the complex indices (eta > 0, k >= 0).
std::vector<std::complex<double>> parse_conductor_channels(std::string_view what, std::string_view text) {
  std::vector<std::complex<double>> ior;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = text.find(';', start);
    const std::string_view item = text.substr(start, end == std::string_view::npos ? text.size() - start : end - start);
    const std::string name = fmt::format("{} channel {}", what, ior.size() + 1);
    const std::vector<std::string_view> parts = split_list(name, item, 2, 2);
    const double eta = parse_double(name + " eta", parts[0], Interval{0.0, kInf, true, false});
    const double k = parse_double(name + " k", parts[1], Interval{0.0, kInf});
    ior.emplace_back(eta, k);
    if (ior.size() > std::size_t(Material::kMaxChannels)) {
      throw ParseError(fmt::format("{} {}: more than {} channels", what, quote_excerpt(text), Material::kMaxChannels));
    }
    if (end == std::string_view::npos) return ior;
    start = end + 1;
  }
}

}  // namespace

Material Material::mirror() { return Material{}; }

Material Material::conductor(std::vector<std::complex<double>> ior, std::vector<std::string> channel_names) {
  if (ior.empty() || ior.size() > std::size_t(kMaxChannels)) {
    throw std::invalid_argument(fmt::format("conductor: {} channels (1 to {} expected)", ior.size(), kMaxChannels));
  }
  for (const std::complex<double>& c : ior) {
    if (!(c.real() > 0.0) || !std::isfinite(c.real()) || !(c.imag() >= 0.0) || !std::isfinite(c.imag())) {
      throw std::invalid_argument(fmt::format("conductor: index {} + {} i (eta > 0 and k >= 0, finite)", c.real(), c.imag()));
    }
  }
  if (channel_names.empty()) channel_names = default_channel_names(ior.size());
  if (channel_names.size() != ior.size()) {
    throw std::invalid_argument(fmt::format("conductor: {} channel names for {} channels", channel_names.size(), ior.size()));
  }
  Material m;
  m.kind_ = MaterialKind::conductor;
  m.ior_ = std::move(ior);
  m.names_ = std::move(channel_names);
  return m;
}

Material Material::dielectric(double eta) {
  if (!(eta > 0.0) || !std::isfinite(eta) || eta == 1.0) {
    throw std::invalid_argument(fmt::format("dielectric: eta {} (positive, finite and not 1)", eta));
  }
  Material m;
  m.kind_ = MaterialKind::dielectric;
  m.eta_ = eta;
  return m;
}

Material Material::lambertian(double albedo) {
  if (!(albedo >= 0.0 && albedo <= 1.0)) throw std::invalid_argument(fmt::format("lambertian: albedo {} (in [0, 1])", albedo));
  Material m;
  m.kind_ = MaterialKind::lambertian;
  m.albedo_ = albedo;
  return m;
}

std::string Material::describe() const {
  switch (kind_) {
    case MaterialKind::mirror: return "mirror";
    case MaterialKind::dielectric: return fmt::format("dielectric:{}", eta_);
    case MaterialKind::lambertian: return fmt::format("lambertian:{}", albedo_);
    case MaterialKind::conductor: break;
  }
  std::string s = "conductor:";
  for (std::size_t c = 0; c < ior_.size(); ++c) s += fmt::format("{}{},{}", c ? ";" : "", ior_[c].real(), ior_[c].imag());
  return s;
}

Material parse_material(std::string_view what, std::string_view text) {
  if (text == "mirror") return Material::mirror();
  if (has_kind(text, "conductor") && text.size() > 10) {
    return Material::conductor(parse_conductor_channels(what, argument_of(text, "conductor")));
  }
  if (has_kind(text, "dielectric") && text.size() > 11) {
    const double eta = parse_double(fmt::format("{} eta", what), argument_of(text, "dielectric"),
                                    Interval{0.0, kInf, true, false});
    if (eta == 1.0) throw ParseError(fmt::format("{} {}: eta 1 is no interface", what, quote_excerpt(text)));
    return Material::dielectric(eta);
  }
  if (text == "lambertian") return Material::lambertian();
  if (has_kind(text, "lambertian") && text.size() > 11) {
    return Material::lambertian(parse_double(fmt::format("{} albedo", what), argument_of(text, "lambertian"), Interval{0.0, 1.0}));
  }
  throw ParseError(fmt::format("{} {}: unknown material (expected mirror, conductor:ETA,K[;ETA,K...], dielectric:ETA "
                               "or lambertian[:ALBEDO])",
                               what, quote_excerpt(text)));
}

namespace {

// A cosine-distributed direction about the unit normal m (Malley's method: a uniform disk point lifted).
Vec3<double> cosine_direction(const Vec3<double>& m, const Vec2<double>& u) {
  const double r = std::sqrt(u.x()), phi = 2.0 * kPi<double> * u.y();
  Vec3<double> b1, b2;
  orthonormal_basis(m, b1, b2);
  const double x = r * std::cos(phi), y = r * std::sin(phi);
  return (x * b1 + y * b2 + safe_sqrt(1.0 - x * x - y * y) * m).normalized();
}

}  // namespace

FacetEvent scatter_on_facet(const Material& material, const Vec3<double>& wi, const Vec3<double>& m, bool inside,
                            const Vec2<double>& u, std::span<double> factors) {
  const double cos_i = std::clamp(wi.dot(m), 0.0, 1.0);
  switch (material.kind()) {
    case MaterialKind::mirror:
      factors[0] = 1.0;
      return {reflect(wi, m), false};
    case MaterialKind::conductor:
      for (int c = 0; c < material.channels(); ++c) factors[std::size_t(c)] = fresnel_conductor(cos_i, material.ior(c));
      return {reflect(wi, m), false};
    case MaterialKind::lambertian:
      factors[0] = material.albedo();
      return {cosine_direction(m, u), false};
    case MaterialKind::dielectric: break;
  }
  factors[0] = 1.0;
  const double eta = inside ? 1.0 / material.eta() : material.eta();  // n_transmitted / n_incident
  Vec3<double> refracted;
  if (u.x() < fresnel_dielectric(cos_i, eta) || !refract(wi, m, eta, refracted)) return {reflect(wi, m), false};
  return {refracted, true};
}

}  // namespace microsim
