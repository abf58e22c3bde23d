// microsim: equal-area direction bins and adaptive cubature of a pdf over them (see binning.h).
#include "stats/binning.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <queue>
#include <stdexcept>

namespace microsim {
namespace {

constexpr double kTwoPi = 2 * kPi<double>;

// Gauss-Kronrod (7, 15) rule on [-1, 1]: Kronrod abscissae x_k (descending, the last is 0) and
// weights; the Gauss 7-point rule uses every second abscissa (indices 1, 3, 5, 7). Standard constants
// (Kronrod 1965; Piessens et al. 1983, QUADPACK).
constexpr std::array<double, 8> kKronrodX = {
    0.991455371120812639206854697526329, 0.949107912342758524526189684047851, 0.864864423359769072789712788640926,
    0.741531185599394439863864773280788, 0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
    0.207784955007898467600689403773245, 0.0};
constexpr std::array<double, 8> kKronrodW = {
    0.022935322010529224963732008058970, 0.063092092629978553290700663189204, 0.104790010322250183839876322541518,
    0.140653259715525918745189590510238, 0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
    0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
constexpr std::array<double, 4> kGaussW = {0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                                           0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

// The 15 nodes of the rule in ascending order: node i has abscissa sign * kKronrodX[k].
struct Rule15 {
  std::array<double, 15> x{}, wk{}, wg{};  // wg is 0 on the Kronrod-only nodes
  Rule15() {
    for (int i = 0; i < 15; ++i) {
      const int k = i < 7 ? i : 14 - i;
      x[i] = (i < 7 ? -1.0 : 1.0) * kKronrodX[k];
      wk[i] = kKronrodW[k];
      wg[i] = (k % 2 == 1) ? kGaussW[k / 2] : 0.0;
    }
  }
};
const Rule15& rule15() {
  static const Rule15 r;
  return r;
}

// A rectangle in (theta, phi) of the parameter space.
struct Cell {
  double t0, t1, p0, p1;
  double value = 0, error = 0;
  // The error's share along theta and along phi (see nested): error <= error_theta + error_phi.
  double error_theta = 0, error_phi = 0;
};

// Angular extent of the longer side of a cell (phi side measured on the widest latitude).
double theta_side(const Cell& c) { return c.t1 - c.t0; }
double phi_side(const Cell& c) {
  const double half_pi = kPi<double> / 2;
  const double max_sin = (c.t0 <= half_pi && c.t1 >= half_pi) ? 1.0 : std::max(std::sin(c.t0), std::sin(c.t1));
  return (c.p1 - c.p0) * max_sin;
}
std::pair<Cell, Cell> split_along(const Cell& c, bool along_theta) {
  Cell a = c, b = c;
  if (along_theta) {
    const double m = 0.5 * (c.t0 + c.t1);
    a.t1 = m;
    b.t0 = m;
  } else {
    const double m = 0.5 * (c.p0 + c.p1);
    a.p1 = m;
    b.p0 = m;
  }
  return {a, b};
}
std::pair<Cell, Cell> split(const Cell& c) { return split_along(c, theta_side(c) >= phi_side(c)); }

double phi_of(const Vec3<double>& u) {
  double phi = std::atan2(u.y(), u.x());  // atan2(0, 0) = 0: the pole has phi = 0 (math.h convention)
  if (phi < 0) phi += kTwoPi;
  return phi >= kTwoPi ? 0.0 : phi;
}

}  // namespace

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

Vec3<double> DirectionBinning::from_param(const Vec3<double>& u) const {
  if (kind_ == BinningKind::sphere) return u;
  const Vec3<double> m = normalized_or_zero(Vec3<double>(ax_ * u.x(), ay_ * u.y(), u.z()));
  if (domain_ == SampleDomain::microfacet_normal) return m;
  return reflect(wi_, m);
}

double DirectionBinning::jacobian(const Vec3<double>& u) const {
  if (kind_ == BinningKind::sphere) return 1.0;
  const Vec3<double> au(ax_ * u.x(), ay_ * u.y(), u.z());
  const double len = au.norm();
  if (!(len > 0)) return 0.0;
  // |dm/du| = det(A) / |A u|^3 (the direction map u -> normalize(A u)).
  double j = ax_ * ay_ / (len * len * len);
  if (domain_ == SampleDomain::reflected_direction) {
    // |dwo/dm| = 4 |wi . m| for wo = reflect(wi, m). The half vector of wi and wo always faces wi, so a
    // u whose m faces away from wi is the image of no direction: its cell measure is 0.
    const double wm = wi_.dot(au / len);
    if (!(wm > 0)) return 0.0;
    j *= 4 * wm;
  }
  return j;
}

std::optional<int> DirectionBinning::bin_of(const Vec3<double>& direction) const {
  const auto u = to_param(direction);
  if (!u) return std::nullopt;
  const double dz = (z_max_ - z_min_) / rows_;
  const int row = std::clamp(int(std::floor((z_max_ - u->z()) / dz)), 0, rows_ - 1);
  const int col = std::clamp(int(std::floor(phi_of(*u) / (kTwoPi / cols()))), 0, cols() - 1);
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

std::vector<double> DirectionBinning::integrate(const std::function<double(const Vec3<double>&)>& pdf) const {
  IntegrationOptions options;
  // The lobe parameterization spreads the lobe over the whole parameter space: its own lattice is a
  // harmless focus set. A sphere binning knows nothing of the lobe; pass focus for narrow lobes.
  if (kind_ == BinningKind::lobe) options.focus = lattice_directions(4096);
  return integrate(pdf, options).probability;
}

BinIntegrals DirectionBinning::integrate(const std::function<double(const Vec3<double>&)>& pdf,
                                         const IntegrationOptions& options) const {
  const Rule15& rule = rule15();
  const int n_bins = size();
  const double dz = (z_max_ - z_min_) / rows_;
  const double dphi = kTwoPi / cols();

  // Focus points in parameter-space (theta, phi), bucketed by bin.
  using FocusBuckets = std::vector<std::vector<std::pair<double, double>>>;
  auto bucket_focus = [&](const std::vector<Vec3<double>>& focus, FocusBuckets& by_bin) {
    for (const Vec3<double>& f : focus) {
      const auto u = to_param(f);
      if (!u) continue;
      const auto bin = bin_of(f);
      by_bin[*bin].emplace_back(std::acos(std::clamp(u->z(), -1.0, 1.0)), phi_of(*u));
    }
  };
  FocusBuckets focus_by_bin(n_bins);
  bucket_focus(options.focus, focus_by_bin);

  // g(theta, phi) = pdf(w(u)) |dw/du| sin(theta): the integrand per unit d theta d phi.
  // The integrand at u(theta, phi) per unit d theta d phi: pdf(w(u)) |dw/du| sin(theta).
  auto integrand = [&](double theta, double phi) {
    const double st = std::sin(theta);
    const Vec3<double> u(st * std::cos(phi), st * std::sin(phi), std::cos(theta));
    return pdf(from_param(u)) * jacobian(u) * st;
  };
  const auto& breaks = options.breaks;
  auto break_value = [&](std::size_t k, double theta, double phi) {
    const double st = std::sin(theta);
    return breaks[k](from_param(Vec3<double>(st * std::cos(phi), st * std::sin(phi), std::cos(theta))));
  };
  // Break-function values on the 15 inner lines x 17 points (the line's two ends and its 15 nodes) of
  // a cell, inner direction theta (theta_inner) or phi; returns how many lines see a sign change.
  const std::size_t n_breaks = breaks.size();
  auto break_grid = [&](const Cell& c, bool theta_inner, std::vector<double>& values, long long& evals) {
    const double i0 = theta_inner ? c.t0 : c.p0, i1 = theta_inner ? c.t1 : c.p1;
    const double o0 = theta_inner ? c.p0 : c.t0, o1 = theta_inner ? c.p1 : c.t1;
    values.resize(n_breaks * 15 * 17);
    int lines_cut = 0;
    for (int j = 0; j < 15; ++j) {
      const double outer = 0.5 * (o0 + o1) + 0.5 * (o1 - o0) * rule.x[j];
      bool cut = false;
      for (std::size_t b = 0; b < n_breaks; ++b) {
        for (int i = 0; i < 17; ++i) {
          const double inner = i == 0 ? i0 : i == 16 ? i1 : 0.5 * (i0 + i1) + 0.5 * (i1 - i0) * rule.x[i - 1];
          const double v = theta_inner ? break_value(b, inner, outer) : break_value(b, outer, inner);
          values[(b * 15 + j) * 17 + i] = v;
          if (i > 0 && (v >= 0) != (values[(b * 15 + j) * 17 + i - 1] >= 0)) cut = true;
        }
      }
      evals += static_cast<long long>(n_breaks) * 17;
      lines_cut += cut;
    }
    return lines_cut;
  };
  // Nested Gauss-Kronrod (K15 x K15, error against G7 x G7) over a cell, the inner integral along theta
  // (theta_inner) or along phi. Each inner line is cut where a break function changes sign between
  // two of its 17 grid points; the root is found by the Illinois variant of regula falsi (Dowell &
  // Jarratt 1971) and the line integrated piecewise.
  auto nested = [&](Cell& c, bool theta_inner, const std::vector<double>& grid, long long& evals) {
    const double i0 = theta_inner ? c.t0 : c.p0, i1 = theta_inner ? c.t1 : c.p1;
    const double o0 = theta_inner ? c.p0 : c.t0, o1 = theta_inner ? c.p1 : c.t1;
    const double oc = 0.5 * (o0 + o1), oh = 0.5 * (o1 - o0);
    const double ic = 0.5 * (i0 + i1), ih = 0.5 * (i1 - i0);
    auto f = [&](double inner, double outer) { return theta_inner ? integrand(inner, outer) : integrand(outer, inner); };
    auto brk = [&](std::size_t b, double inner, double outer) {
      return theta_inner ? break_value(b, inner, outer) : break_value(b, outer, inner);
    };
    std::array<double, 17> xs{};
    xs[0] = i0;
    for (int i = 0; i < 15; ++i) xs[i + 1] = ic + ih * rule.x[i];
    xs[16] = i1;
    double k = 0, g = 0, inner_err = 0, outer_err = 0;
    for (int j = 0; j < 15; ++j) {
      const double outer = oc + oh * rule.x[j];
      constexpr int kMaxCuts = 32;
      std::array<double, kMaxCuts + 2> cuts{};
      int n_cuts = 0;
      cuts[n_cuts++] = i0;
      for (std::size_t b = 0; b < n_breaks; ++b) {
        const double* v = &grid[(b * 15 + j) * 17];
        for (int i = 1; i < 17; ++i) {
          if ((v[i] >= 0) == (v[i - 1] >= 0)) continue;
          double lo = xs[i - 1], hi = xs[i], flo = v[i - 1], fhi = v[i];
          int side = 0;
          for (int it = 0; it < 60 && hi - lo > 1e-14 * std::max(1.0, std::abs(hi)); ++it) {
            double x = (lo * fhi - hi * flo) / (fhi - flo);
            if (!(x > lo && x < hi)) x = 0.5 * (lo + hi);
            const double fx = brk(b, x, outer);
            evals += 1;
            if ((fx >= 0) == (flo >= 0)) {
              lo = x;
              flo = fx;
              if (side == -1) fhi *= 0.5;  // Illinois: halve the stale end's value
              side = -1;
            } else {
              hi = x;
              fhi = fx;
              if (side == 1) flo *= 0.5;
              side = 1;
            }
          }
          if (n_cuts < kMaxCuts + 1) cuts[n_cuts++] = 0.5 * (lo + hi);
        }
      }
      double lk = 0, lg = 0;
      if (n_cuts == 1) {
        for (int i = 0; i < 15; ++i) {
          const double val = f(xs[i + 1], outer);
          lk += rule.wk[i] * val;
          lg += rule.wg[i] * val;
        }
        evals += 15;
        lk *= ih;
        lg *= ih;
      } else {
        cuts[n_cuts++] = i1;
        std::sort(cuts.begin(), cuts.begin() + n_cuts);
        for (int s = 0; s + 1 < n_cuts; ++s) {
          const double a = cuts[s], b = cuts[s + 1];
          if (!(b > a)) continue;
          const double mc = 0.5 * (a + b), mh = 0.5 * (b - a);
          double ks = 0, gs = 0;
          for (int i = 0; i < 15; ++i) {
            const double val = f(mc + mh * rule.x[i], outer);
            ks += rule.wk[i] * val;
            gs += rule.wg[i] * val;
          }
          evals += 15;
          lk += ks * mh;
          lg += gs * mh;
        }
      }
      k += rule.wk[j] * lk;
      g += rule.wg[j] * lg;
      inner_err += rule.wk[j] * (lk - lg);
      outer_err += (rule.wk[j] - rule.wg[j]) * lg;
    }
    c.value = k * oh;
    c.error = std::abs(k - g) * oh;
    // k - g = inner_err + outer_err: the inner rule's error (Kronrod against Gauss on each line) and the
    // outer rule's; where the error comes from says which side a split should halve.
    (theta_inner ? c.error_theta : c.error_phi) = std::abs(inner_err) * oh;
    (theta_inner ? c.error_phi : c.error_theta) = std::abs(outer_err) * oh;
  };
  // With break curves, the inner direction is the one whose lines the curves cross most often: lines
  // parallel to a curve can miss it (a sliver between two nodes), lines across it cannot.
  auto evaluate = [&](Cell& c, long long& evals) {
    if (n_breaks == 0) {
      static const std::vector<double> none;
      nested(c, true, none, evals);
      return;
    }
    std::vector<double> theta_grid, phi_grid;
    const int theta_cuts = break_grid(c, true, theta_grid, evals);
    // Every theta line cut: the phi order cannot see more crossings.
    const int phi_cuts = theta_cuts == 15 ? 0 : break_grid(c, false, phi_grid, evals);
    if (phi_cuts > theta_cuts) {
      nested(c, false, phi_grid, evals);
    } else {
      nested(c, true, theta_grid, evals);
    }
  };

  std::vector<double> probability(n_bins, 0.0), error(n_bins, 0.0);
  std::vector<long long> evaluations(n_bins, 0);
  std::vector<char> converged(n_bins, 0);
  auto tolerance = [&](double value) { return std::max(options.abs_tolerance, options.rel_tolerance * std::abs(value)); };
  // One bin: focus phase, error-driven refinement, then (directed_budget > 0) up to directed_budget
  // splits along the side that carries the error.
  auto integrate_bin = [&](int bin, const FocusBuckets& focus_by_bin, int directed_budget) {
    const int row = bin / cols(), col = bin % cols();
    const double z_hi = z_max_ - row * dz;
    const double z_lo = row == rows_ - 1 ? z_min_ : z_max_ - (row + 1) * dz;
    // Band pieces between the z breaks (a jump of the pdf then lies on a cell edge).
    std::vector<double> zs = {z_hi};
    std::vector<double> breaks = options.z_breaks;
    std::sort(breaks.begin(), breaks.end(), std::greater<>());
    for (double b : breaks)
      if (b < z_hi && b > z_lo) zs.push_back(b);
    zs.push_back(z_lo);

    // Phase 1: split every cell that holds more than max_focus_per_cell focus points.
    std::vector<Cell> leaves;
    struct Pending {
      Cell cell;
      std::vector<std::pair<double, double>> focus;
    };
    // A crowded cell is cut where its focus points leave a large part of it empty along theta or phi
    // (isolating a thin lobe from the empty rest, so that cells shrink to the lobe's own shape), else
    // halved along its longer side.
    auto split_around_focus = [](const Cell& c, const std::vector<std::pair<double, double>>& focus,
                                 double min_size) {
      double ft0 = c.t1, ft1 = c.t0, fp0 = c.p1, fp1 = c.p0;
      for (const auto& f : focus) {
        ft0 = std::min(ft0, f.first);
        ft1 = std::max(ft1, f.first);
        fp0 = std::min(fp0, f.second);
        fp1 = std::max(fp1, f.second);
      }
      const double occupied_theta = (ft1 - ft0) / (c.t1 - c.t0), occupied_phi = (fp1 - fp0) / (c.p1 - c.p0);
      std::vector<Cell> pieces;
      if (std::min(occupied_theta, occupied_phi) < 0.25) {
        const bool along_theta = occupied_theta <= occupied_phi;
        const double lo = along_theta ? c.t0 : c.p0, hi = along_theta ? c.t1 : c.p1;
        const double f0 = along_theta ? ft0 : fp0, f1 = along_theta ? ft1 : fp1;
        const double pad = std::max(0.25 * (f1 - f0), min_size);
        const double cuts[4] = {lo, std::max(lo, f0 - pad), std::min(hi, f1 + pad), hi};
        for (int i = 0; i < 3; ++i) {
          if (!(cuts[i + 1] > cuts[i])) continue;
          Cell piece = c;
          (along_theta ? piece.t0 : piece.p0) = cuts[i];
          (along_theta ? piece.t1 : piece.p1) = cuts[i + 1];
          pieces.push_back(piece);
        }
      }
      if (pieces.size() < 2) {  // nothing to cut away: halve
        auto [a, b] = split(c);
        pieces = {a, b};
      }
      std::vector<Pending> out;
      for (const Cell& piece : pieces) out.push_back({piece, {}});
      for (const auto& f : focus) {
        for (std::size_t i = 0; i < out.size(); ++i) {
          const Cell& q = out[i].cell;
          const bool last = i + 1 == out.size();
          if (last || (f.first >= q.t0 && f.first <= q.t1 && f.second >= q.p0 && f.second <= q.p1)) {
            out[i].focus.push_back(f);
            break;
          }
        }
      }
      return out;
    };
    std::vector<Pending> stack;
    for (std::size_t i = 0; i + 1 < zs.size(); ++i) {
      Pending p{{std::acos(std::clamp(zs[i], -1.0, 1.0)), std::acos(std::clamp(zs[i + 1], -1.0, 1.0)), col * dphi,
                 (col + 1) * dphi},
                {}};
      for (const auto& f : focus_by_bin[bin])
        if (f.first >= p.cell.t0 && f.first <= p.cell.t1) p.focus.push_back(f);
      stack.push_back(std::move(p));
    }
    while (!stack.empty()) {
      Pending p = std::move(stack.back());
      stack.pop_back();
      const bool crowded = int(p.focus.size()) > options.max_focus_per_cell &&
                           std::max(theta_side(p.cell), phi_side(p.cell)) > options.min_cell_size;
      if (!crowded) {
        leaves.push_back(p.cell);
        continue;
      }
      for (Pending& piece : split_around_focus(p.cell, p.focus, options.min_cell_size))
        stack.push_back(std::move(piece));
    }

    // Phase 2: error-driven refinement of the worst cell until the bin meets its tolerance.
    auto worse = [](const Cell& a, const Cell& b) { return a.error < b.error; };
    std::priority_queue<Cell, std::vector<Cell>, decltype(worse)> queue(worse);
    double value = 0, err = 0;
    long long evals = 0;
    for (Cell& c : leaves) {
      evaluate(c, evals);
      value += c.value;
      err += c.error;
      queue.push(c);
    }
    // Replaces the worst cell by its two halves along theta (along_theta) or phi.
    auto refine_worst = [&](bool along_theta) {
      const Cell worst = queue.top();
      queue.pop();
      auto [a, b] = split_along(worst, along_theta);
      evaluate(a, evals);
      evaluate(b, evals);
      value += a.value + b.value - worst.value;
      err += a.error + b.error - worst.error;
      queue.push(a);
      queue.push(b);
    };
    int cells = 0;  // refinements in this phase (the focus phase has its own budget, min_cell_size)
    while (err > tolerance(value) && cells < options.max_cells_per_bin && !queue.empty()) {
      const Cell& worst = queue.top();
      if (std::max(theta_side(worst), phi_side(worst)) <= options.min_cell_size) break;
      refine_worst(theta_side(worst) >= phi_side(worst));  // the longer side
      ++cells;
    }
    // Directed phase: halving the longer side resolves a lobe only as finely in its narrow direction
    // as in its long one; a lobe 1e-4 long and 1e-8 wide (alpha 1e-4 at a grazing view, reflected)
    // exhausts the budget above long before. Split the worst cell along the side whose rule error
    // dominates instead, until the bin meets its tolerance.
    for (int directed = 0; directed < directed_budget && !queue.empty() && err > tolerance(value); ++directed) {
      const Cell& worst = queue.top();
      const bool theta_ok = theta_side(worst) > options.min_cell_size, phi_ok = phi_side(worst) > options.min_cell_size;
      if (!theta_ok && !phi_ok) break;
      refine_worst(!phi_ok || (theta_ok && worst.error_theta >= worst.error_phi));
    }
    // Re-sum the leaves (the running sums accumulate cancellation).
    value = 0;
    err = 0;
    while (!queue.empty()) {
      value += queue.top().value;
      err += queue.top().error;
      queue.pop();
    }
    probability[bin] = value;
    error[bin] = err;
    evaluations[bin] += evals;
    converged[bin] = err <= tolerance(value);
  };
  tbb::parallel_for(0, n_bins, [&](int bin) { integrate_bin(bin, focus_by_bin, 0); });
  // Second pass: when the bins' error estimates add up to more than second_pass_total_error, the bins
  // that missed their tolerance are integrated again from scratch with the extra focus points and the
  // directed phase. Bins that converged, and every bin when the total is small, keep their first values.
  double total_error = 0;
  for (int b = 0; b < n_bins; ++b) total_error += error[b];
  std::vector<int> again;
  if (total_error > options.second_pass_total_error)
    for (int b = 0; b < n_bins; ++b)
      if (!converged[b]) again.push_back(b);
  if (!again.empty()) {
    FocusBuckets rich_focus = focus_by_bin;
    bucket_focus(options.second_pass_focus, rich_focus);
    tbb::parallel_for(std::size_t(0), again.size(), [&](std::size_t i) {
      integrate_bin(again[i], rich_focus, options.max_directed_cells_per_bin);
    });
  }

  BinIntegrals result;
  result.probability = std::move(probability);
  result.second_pass_bins = int(again.size());
  for (int b = 0; b < n_bins; ++b) {
    result.total += result.probability[b];
    result.error_estimate += error[b];
    result.evaluations += evaluations[b];
  }
  return result;
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
  j["kind"] = name();
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
