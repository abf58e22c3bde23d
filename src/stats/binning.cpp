// microsim: equal-area direction bins (see binning.h); their cubature is in cubature.cpp.
#include "stats/binning.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microsim {
namespace {

constexpr double kTwoPi = 2 * kPi<double>;

}  // namespace

double param_phi(const Vec3<double>& u) {
  double phi = std::atan2(u.y(), u.x());  // atan2(0, 0) = 0: the pole has phi = 0 (math.h convention)
  if (phi < 0) phi += kTwoPi;
  return phi >= kTwoPi ? 0.0 : phi;
}

std::string to_string(SampleDomain domain) {
  return domain == SampleDomain::microfacet_normal ? "microfacet_normal" : "reflected_direction";
}

SampleDomain sample_domain_from_string(const std::string& s) {
  if (s == "microfacet_normal") return SampleDomain::microfacet_normal;
  if (s == "reflected_direction") return SampleDomain::reflected_direction;
  throw std::invalid_argument(fmt::format("unknown sample domain '{}'", s));
}

DirectionBinning DirectionBinning::sphere(int rows) {
  if (rows < 1 || rows % 2 == 0 || rows > kMaxBinningRows)
    throw std::invalid_argument(
        fmt::format("sphere binning needs an odd number of rows in [1, {}], got {}", kMaxBinningRows, rows));
  DirectionBinning b;
  b.kind_ = BinningKind::sphere;
  b.rows_ = rows;
  b.z_min_ = -1;
  b.z_max_ = 1;
  return b;
}

DirectionBinning DirectionBinning::hemispheres(int rows_per_hemisphere) {
  if (rows_per_hemisphere < 1 || 2 * rows_per_hemisphere > kMaxBinningRows)
    throw std::invalid_argument(fmt::format("hemispheres binning needs rows per hemisphere in [1, {}], got {}",
                                            kMaxBinningRows / 2, rows_per_hemisphere));
  DirectionBinning b;
  b.kind_ = BinningKind::sphere;
  b.rows_ = 2 * rows_per_hemisphere;
  b.z_min_ = -1;
  b.z_max_ = 1;
  return b;
}

DirectionBinning DirectionBinning::lobe(const GGX<double>& ggx, const Vec3<double>& wi, SampleDomain domain, int rows) {
  if (rows < 1 || rows > kMaxBinningRows)
    throw std::invalid_argument(fmt::format("lobe binning needs rows in [1, {}], got {}", kMaxBinningRows, rows));
  const double n = wi.norm();
  if (!(n > 0) || !std::isfinite(n)) throw std::invalid_argument("lobe binning needs a finite non-zero view");
  DirectionBinning b;
  b.kind_ = BinningKind::lobe;
  b.rows_ = rows;
  b.ax_ = ggx.alpha_x();
  b.ay_ = ggx.alpha_y();
  b.wi_ = wi / n;
  b.domain_ = domain;
  // Back-side views (wi.z < 0) see the lower side: their normals and half vectors are in u.z <= 0.
  if (b.wi_.z() < 0) {
    b.z_min_ = -1;
    b.z_max_ = 0;
  } else {
    b.z_min_ = 0;
    b.z_max_ = 1;
  }
  return b;
}

std::optional<Vec3<double>> DirectionBinning::to_param(const Vec3<double>& direction) const {
  if (!direction.allFinite()) return std::nullopt;
  const double n = direction.norm();
  if (!(n > 0)) return std::nullopt;
  const Vec3<double> w = direction / n;
  if (kind_ == BinningKind::sphere) return w;
  Vec3<double> m = w;
  if (domain_ == SampleDomain::reflected_direction) {
    // Half vector of wi and wo; undefined for wo = -wi (a single direction).
    m = normalized_or_zero(Vec3<double>(wi_ + w));
    if (m.isZero()) return std::nullopt;
  }
  const Vec3<double> u = normalized_or_zero(Vec3<double>(m.x() / ax_, m.y() / ay_, m.z()));
  if (u.isZero()) return std::nullopt;
  if (u.z() < z_min_ || u.z() > z_max_) return std::nullopt;  // on the far side of the parameter space
  return u;
}

std::optional<int> DirectionBinning::bin_of(const Vec3<double>& direction) const {
  const auto u = to_param(direction);
  if (!u) return std::nullopt;
  const double dz = (z_max_ - z_min_) / rows_;
  const int row = std::clamp(int(std::floor((z_max_ - u->z()) / dz)), 0, rows_ - 1);
  const int col = std::clamp(int(std::floor(param_phi(*u) / (kTwoPi / cols()))), 0, cols() - 1);
  return row * cols() + col;
}

BinBounds DirectionBinning::bounds(int bin) const {
  const int row = bin / cols(), col = bin % cols();
  const double dz = (z_max_ - z_min_) / rows_;
  const double z_hi = z_max_ - row * dz;
  const double z_lo = row == rows_ - 1 ? z_min_ : z_max_ - (row + 1) * dz;
  const double to_deg = 180.0 / kPi<double>;
  const double dphi = 360.0 / cols();
  return {std::acos(std::clamp(z_hi, -1.0, 1.0)) * to_deg, std::acos(std::clamp(z_lo, -1.0, 1.0)) * to_deg,
          col * dphi, (col + 1) * dphi};
}

double DirectionBinning::center_theta_deg(int bin) const {
  const int row = bin / cols();
  const double dz = (z_max_ - z_min_) / rows_;
  return std::acos(std::clamp(z_max_ - (row + 0.5) * dz, -1.0, 1.0)) * 180.0 / kPi<double>;
}

double DirectionBinning::center_phi_deg(int bin) const { return (bin % cols() + 0.5) * 360.0 / cols(); }

std::string DirectionBinning::describe_bin(int bin) const {
  const BinBounds b = bounds(bin);
  return fmt::format("theta {:.2f}..{:.2f} phi {:.1f}..{:.1f} ({})", b.theta_min_deg, b.theta_max_deg, b.phi_min_deg,
                     b.phi_max_deg, name());
}

std::vector<Vec3<double>> DirectionBinning::lattice_directions(int n) const {
  std::vector<Vec3<double>> out;
  out.reserve(std::max(n, 0));
  const double golden = (std::sqrt(5.0) - 1) / 2;  // Fibonacci lattice: phi steps by the golden ratio
  for (int k = 0; k < n; ++k) {
    const double z = z_max_ - (k + 0.5) / n * (z_max_ - z_min_);
    const double frac = k * golden - std::floor(k * golden);
    const double phi = kTwoPi * frac;
    const double s = safe_sqrt(1 - z * z);
    out.push_back(from_param(Vec3<double>(s * std::cos(phi), s * std::sin(phi), z)));
  }
  return out;
}

std::vector<Vec3<double>> DirectionBinning::visible_edge_directions(int rings, int per_ring) const {
  std::vector<Vec3<double>> out;
  if (kind_ != BinningKind::lobe) return out;
  const Vec3<double> v = Vec3<double>(ax_ * wi_.x(), ay_ * wi_.y(), wi_.z()).normalized();
  Vec3<double> t1, t2;
  orthonormal_basis(v, t1, t2);
  for (int k = 0; k < rings; ++k) {
    const double eta = 0.5 * std::exp2(-k / 4.0);
    for (int j = 0; j < per_ring; ++j) {
      const double psi = kTwoPi * (j + 0.5) / per_ring;
      const Vec3<double> u = (std::cos(eta) * (std::cos(psi) * t1 + std::sin(psi) * t2) + std::sin(eta) * v).normalized();
      if (u.z() >= z_min_ && u.z() <= z_max_) out.push_back(from_param(u));
    }
  }
  return out;
}

nlohmann::json DirectionBinning::describe() const {
  nlohmann::json j;
  j["kind"] = kind_ == BinningKind::sphere && rows_ % 2 == 0 ? "hemispheres" : name();
  j["rows"] = rows_;
  j["cols"] = cols();
  j["z_min"] = z_min_;
  j["z_max"] = z_max_;
  if (kind_ == BinningKind::lobe) {
    j["alpha"] = {ax_, ay_};
    j["wi"] = {wi_.x(), wi_.y(), wi_.z()};
    j["domain"] = to_string(domain_);
    j["parameterization"] =
        "u = normalize(mx/ax, my/ay, mz) with m the sample (microfacet_normal) or normalize(wi + sample) "
        "(reflected_direction)";
  } else {
    j["parameterization"] = "u = the sample direction";
  }
  j["bin_order"] =
      "bin = row * cols + col; rows uniform in u.z from z_max (row 0) down to z_min; cols uniform in "
      "phi = atan2(u.y, u.x) in [0, 2 pi) from phi = 0";
  return j;
}

DirectionBinning DirectionBinning::from_description(const nlohmann::json& d) {
  try {
    const std::string kind = d.at("kind").get<std::string>();
    // Range-checked before narrowing: get<int>() of 1e10 rows would wrap.
    const nlohmann::json& rows_json = d.at("rows");
    if (!rows_json.is_number_integer() || rows_json.get<std::int64_t>() < 1 ||
        rows_json.get<std::int64_t>() > kMaxBinningRows)
      throw std::invalid_argument(
          fmt::format("binning description: rows must be an integer in [1, {}], got {}", kMaxBinningRows,
                      rows_json.dump().substr(0, 40)));
    const int rows = rows_json.get<int>();
    if (d.contains("cols") && (!d.at("cols").is_number_integer() || d.at("cols").get<std::int64_t>() != 2 * rows))
      throw std::invalid_argument("binning description: cols must be 2 * rows");
    if (kind == "sphere") return sphere(rows);
    if (kind == "hemispheres") {
      if (rows % 2 != 0) throw std::invalid_argument("binning description: hemispheres need an even number of rows");
      return hemispheres(rows / 2);
    }
    if (kind == "lobe") {
      const auto a = d.at("alpha");
      const auto w = d.at("wi");
      if (a.size() != 2 || w.size() != 3) throw std::invalid_argument("binning description: bad alpha or wi");
      return lobe(GGX<double>(a[0].get<double>(), a[1].get<double>()),
                  Vec3<double>(w[0].get<double>(), w[1].get<double>(), w[2].get<double>()),
                  sample_domain_from_string(d.at("domain").get<std::string>()), rows);
    }
    throw std::invalid_argument(fmt::format("binning description: unknown kind '{}'", kind));
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(fmt::format("binning description: {}", e.what()));
  }
}

}  // namespace microsim
