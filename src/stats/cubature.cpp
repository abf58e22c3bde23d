// microsim: the probability of every bin of a DirectionBinning under a pdf, by adaptive cubature in the
// (theta, phi) of the parameter space (see binning.h). One bin at a time: its band is cut at the z breaks,
// cells crowded with focus points are split (focus phase), then the worst cell is halved until the bin
// meets its tolerance (error-driven phase), and in the second pass split along the side that carries the
// error (directed phase). A cell is integrated by a nested Gauss-Kronrod rule whose inner lines are cut
// where a break curve crosses them.
#include "stats/binning.h"

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <boost/math/tools/toms748_solve.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <queue>

namespace microsim {
namespace {

using Pdf = std::function<double(const Vec3<double>&)>;

// The Gauss-Kronrod (7, 15) rule on [-1, 1] (Kronrod 1965; Piessens et al. 1983, QUADPACK), its 15 nodes
// in ascending order: abscissa x, Kronrod weight wk, and the weight wg of the embedded 7-point Gauss rule
// (0 on the Kronrod-only nodes). The constants are Boost.Math's, whose tables hold the non-negative
// abscissae ascending from 0 (so node i has table index |7 - i|; the Gauss nodes are the even indices).
struct Rule15 {
  std::array<double, 15> x{}, wk{}, wg{};
  Rule15() {
    using Kronrod = boost::math::quadrature::gauss_kronrod<double, 15>;
    using Gauss = boost::math::quadrature::gauss<double, 7>;
    for (int i = 0; i < 15; ++i) {
      const int k = std::abs(7 - i);
      x[i] = (i < 7 ? -1.0 : 1.0) * Kronrod::abscissa()[k];
      wk[i] = Kronrod::weights()[k];
      wg[i] = k % 2 == 0 ? Gauss::weights()[k / 2] : 0.0;
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
  // The error's share along theta and along phi (see BinCubature::nested): error <= error_theta + error_phi.
  double error_theta = 0, error_phi = 0;
};

// Angular extent of the sides of a cell (the phi side measured on its widest latitude).
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

// ---- focus points ------------------------------------------------------------------------------------

// A focus point as (theta, phi) of its parameter-space point; the focus points of every bin.
using FocusPoint = std::pair<double, double>;
using FocusBuckets = std::vector<std::vector<FocusPoint>>;

// Appends each direction of `focus` (sample domain) to the bucket of its bin; directions outside the
// parameter space are dropped.
void bucket_focus(const DirectionBinning& binning, const std::vector<Vec3<double>>& focus, FocusBuckets& by_bin) {
  for (const Vec3<double>& f : focus) {
    const auto u = binning.to_param(f);
    if (!u) continue;
    const auto bin = binning.bin_of(f);
    by_bin[*bin].emplace_back(std::acos(std::clamp(u->z(), -1.0, 1.0)), param_phi(*u));
  }
}

// A cell of the focus phase and the focus points inside it.
struct Pending {
  Cell cell;
  std::vector<FocusPoint> focus;
};

// The pieces a crowded cell is cut into: where its focus points leave a large part of it empty along
// theta or phi, the occupied strip (padded) and the empty rest, so that cells shrink to a thin lobe's own
// shape; else its two halves along the longer side.
std::vector<Cell> cut_around_focus(const Cell& c, const std::vector<FocusPoint>& focus, double min_size) {
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
  return pieces;
}

// Splits a crowded cell (cut_around_focus) and hands each focus point to the first piece holding it (the
// last piece takes any that round-off leaves outside every piece).
std::vector<Pending> split_around_focus(const Cell& c, const std::vector<FocusPoint>& focus, double min_size) {
  std::vector<Pending> out;
  for (const Cell& piece : cut_around_focus(c, focus, min_size)) out.push_back({piece, {}});
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
}

// A cell cut in four (in two along a side already at min_size), its focus points handed to the quarter
// holding each: a blind cell (BinCubature::blind) is resolved alike whether its mass is a strip along an
// edge or across it.
std::vector<Pending> quarters(const Pending& p, double min_size) {
  std::vector<Cell> halves = {p.cell};
  for (bool along_theta : {true, false}) {
    if (!((along_theta ? theta_side(p.cell) : phi_side(p.cell)) > min_size)) continue;
    std::vector<Cell> cut;
    for (const Cell& h : halves) {
      const auto [a, b] = split_along(h, along_theta);
      cut.push_back(a);
      cut.push_back(b);
    }
    halves = std::move(cut);
  }
  std::vector<Pending> out;
  for (const Cell& c : halves) out.push_back({c, {}});
  for (const auto& f : p.focus)
    for (Pending& q : out)
      if (f.first >= q.cell.t0 && f.first <= q.cell.t1 && f.second >= q.cell.p0 && f.second <= q.cell.p1) {
        q.focus.push_back(f);
        break;
      }
  return out;
}

// ---- one bin ----------------------------------------------------------------------------------------

// One cell's sides as the inner and outer interval of the nested rule (inner direction theta or phi),
// with the inner line's 17 grid points: its two ends and the 15 nodes of the rule, and their sines and
// cosines (the same on every inner line: computed once per cell, not once per line).
struct CellFrame {
  double i0, i1, o0, o1;
  double oc, oh;              // centre and half-width of the outer interval
  std::array<double, 17> xs;  // grid points along an inner line
  std::array<double, 17> sin_xs, cos_xs;
  CellFrame(const Cell& c, bool theta_inner, const Rule15& rule)
      : i0(theta_inner ? c.t0 : c.p0), i1(theta_inner ? c.t1 : c.p1), o0(theta_inner ? c.p0 : c.t0),
        o1(theta_inner ? c.p1 : c.t1), oc(0.5 * (o0 + o1)), oh(0.5 * (o1 - o0)) {
    const double ic = 0.5 * (i0 + i1), ih = 0.5 * (i1 - i0);
    xs[0] = i0;
    for (int i = 0; i < 15; ++i) xs[i + 1] = ic + ih * rule.x[i];
    xs[16] = i1;
    for (int i = 0; i < 17; ++i) sin_xs[i] = std::sin(xs[i]), cos_xs[i] = std::cos(xs[i]);
  }
};

// Where break curves cut one inner line: its start, then one root per sign change (at most kMaxCuts).
struct LineCuts {
  static constexpr int kMaxCuts = 32;
  std::array<double, kMaxCuts + 2> at{};
  int n = 0;
};

// The cells of one bin, worst error on top, with the running sums of their values and errors and the
// evaluations spent on them.
struct Refinement {
  static bool less_error(const Cell& a, const Cell& b) { return a.error < b.error; }
  std::priority_queue<Cell, std::vector<Cell>, decltype(&less_error)> queue{&less_error};
  double value = 0, error = 0;
  long long evaluations = 0;
};

struct BinResult {
  double probability = 0, error = 0;
  long long evaluations = 0;
  bool converged = false;
};

// The cubature of one binning under one pdf: integrate_bin is called concurrently, one bin per call.
class BinCubature {
public:
  BinCubature(const DirectionBinning& binning, const Pdf& pdf, const IntegrationOptions& options)
      : binning_(binning), pdf_(pdf), options_(options), rule_(rule15()), n_breaks_(options.breaks.size()),
        dz_((binning.z_max() - binning.z_min()) / binning.rows()), dphi_(2 * kPi<double> / binning.cols()),
        z_breaks_(options.z_breaks) {
    std::sort(z_breaks_.begin(), z_breaks_.end(), std::greater<>());
  }

  // One bin: focus phase, error-driven refinement, then (directed_budget > 0) up to directed_budget
  // splits along the side that carries the error.
  BinResult integrate_bin(int bin, const std::vector<FocusPoint>& focus, int directed_budget) const {
    Refinement r;
    focus_phase(bin, focus, r);
    refine_longer_sides(r);
    refine_directed(r, directed_budget);
    return resum(r);
  }

private:
  double tolerance(double value) const {
    return std::max(options_.abs_tolerance, options_.rel_tolerance * std::abs(value));
  }

  // The integrand at u(theta, phi) per unit d theta d phi: pdf(w(u)) |dw/du| sin(theta), from the sines and
  // cosines of theta and phi.
  double integrand_of_trig(double st, double ct, double sp, double cp) const {
    const Vec3<double> u(st * cp, st * sp, ct);
    return pdf_(binning_.from_param(u)) * binning_.jacobian(u) * st;
  }
  double break_of_trig(std::size_t k, double st, double ct, double sp, double cp) const {
    return options_.breaks[k](binning_.from_param(Vec3<double>(st * cp, st * sp, ct)));
  }
  double break_value(std::size_t k, double theta, double phi) const {
    return break_of_trig(k, std::sin(theta), std::cos(theta), std::sin(phi), std::cos(phi));
  }
  double break_on_line(bool theta_inner, std::size_t k, double inner, double outer) const {
    return break_value(k, theta_inner ? inner : outer, theta_inner ? outer : inner);
  }

  std::vector<double> band_pieces(int bin) const;
  void focus_phase(int bin, const std::vector<FocusPoint>& focus, Refinement& r) const;
  bool blind(const Cell& c, const std::vector<FocusPoint>& focus, long long& evals) const;
  // Blind cells split per bin at most: a structure thinner than min_cell_size cannot make a bin endless.
  static constexpr int kMaxBlindSplits = 256;
  int break_grid(const CellFrame& f, bool theta_inner, std::vector<double>& values, long long& evals) const;
  double break_root(bool theta_inner, std::size_t k, double outer, double lo, double hi, double flo, double fhi,
                    long long& evals) const;
  void cut_line(const CellFrame& f, bool theta_inner, int j, double outer, const std::vector<double>& grid,
                LineCuts& cuts, long long& evals) const;
  std::pair<double, double> segment_rule(bool theta_inner, double a, double b, double outer, long long& evals) const;
  std::pair<double, double> rule_at_nodes(bool theta_inner, const double* sines, const double* cosines, double outer,
                                          double mh, long long& evals) const;
  std::pair<double, double> line_rule(const CellFrame& f, bool theta_inner, int j, double outer,
                                      const std::vector<double>& grid, long long& evals) const;
  void nested(Cell& c, const CellFrame& f, bool theta_inner, const std::vector<double>& grid, long long& evals) const;
  void evaluate(Cell& c, long long& evals) const;
  void add_evaluated(Refinement& r, const Cell& c) const;
  void refine_worst(Refinement& r, bool along_theta) const;
  void refine_longer_sides(Refinement& r) const;
  void refine_directed(Refinement& r, int budget) const;
  BinResult resum(Refinement& r) const;

  const DirectionBinning& binning_;
  const Pdf& pdf_;
  const IntegrationOptions& options_;
  const Rule15& rule_;
  const std::size_t n_breaks_;
  const double dz_, dphi_;
  std::vector<double> z_breaks_;  // descending
};

// The heights z that bound the pieces of a bin's band: its top, the z breaks inside it (a jump of the pdf
// then lies on a cell edge), its bottom.
std::vector<double> BinCubature::band_pieces(int bin) const {
  const int row = bin / binning_.cols();
  const double z_hi = binning_.z_max() - row * dz_;
  const double z_lo = row == binning_.rows() - 1 ? binning_.z_min() : binning_.z_max() - (row + 1) * dz_;
  std::vector<double> zs = {z_hi};
  for (double b : z_breaks_)
    if (b < z_hi && b > z_lo) zs.push_back(b);
  zs.push_back(z_lo);
  return zs;
}

// Phase 1: the bin's band pieces, every cell holding more than max_focus_per_cell focus points, or blind
// to the mass it holds (blind), split (down to min_cell_size); the cells that are left evaluated into r.
void BinCubature::focus_phase(int bin, const std::vector<FocusPoint>& focus, Refinement& r) const {
  const int col = bin % binning_.cols();
  const std::vector<double> zs = band_pieces(bin);
  std::vector<Pending> stack;
  for (std::size_t i = 0; i + 1 < zs.size(); ++i) {
    Pending p{{std::acos(std::clamp(zs[i], -1.0, 1.0)), std::acos(std::clamp(zs[i + 1], -1.0, 1.0)), col * dphi_,
               (col + 1) * dphi_},
              {}};
    for (const auto& f : focus)
      if (f.first >= p.cell.t0 && f.first <= p.cell.t1) p.focus.push_back(f);
    stack.push_back(std::move(p));
  }
  int blind_splits = 0;
  while (!stack.empty()) {
    Pending p = std::move(stack.back());
    stack.pop_back();
    const bool splittable = std::max(theta_side(p.cell), phi_side(p.cell)) > options_.min_cell_size;
    if (!splittable || int(p.focus.size()) <= options_.max_focus_per_cell) {
      evaluate(p.cell, r.evaluations);
      if (!splittable || blind_splits >= kMaxBlindSplits || !blind(p.cell, p.focus, r.evaluations)) {
        add_evaluated(r, p.cell);
        continue;
      }
      ++blind_splits;
      for (Pending& quarter : quarters(p, options_.min_cell_size)) stack.push_back(std::move(quarter));
      continue;
    }
    for (Pending& piece : split_around_focus(p.cell, p.focus, options_.min_cell_size)) stack.push_back(std::move(piece));
  }
}

// Whether a cell's rule saw nothing (value 0) although the pdf is positive in it: at one of its focus
// points, or just inside one of its edges (the rule's nodes never reach them; a lobe 1e-4 wide along an
// edge of a cell 0.1 wide lies between them and the edge). Its zero error estimate is then false. A value
// too small to matter were it the integrand over the whole cell (an underflowing tail) is not mass.
bool BinCubature::blind(const Cell& c, const std::vector<FocusPoint>& focus, long long& evals) const {
  if (c.value != 0) return false;
  const double negligible = 1e-6 * options_.abs_tolerance / ((c.t1 - c.t0) * (c.p1 - c.p0));
  auto positive = [&](double theta, double phi) {
    evals += 1;
    return integrand_of_trig(std::sin(theta), std::cos(theta), std::sin(phi), std::cos(phi)) > negligible;
  };
  for (const FocusPoint& f : focus)
    if (positive(f.first, f.second)) return true;
  // Probes 1e-6 of a side inside each edge, so that a pdf zero beyond the edge (a hemisphere's) is not seen.
  const double et = 1e-6 * (c.t1 - c.t0), ep = 1e-6 * (c.p1 - c.p0);
  constexpr int kProbes = 17;
  for (int i = 0; i < kProbes; ++i) {
    const double s = double(i) / (kProbes - 1);
    const double theta = c.t0 + et + s * (c.t1 - c.t0 - 2 * et), phi = c.p0 + ep + s * (c.p1 - c.p0 - 2 * ep);
    if (positive(theta, c.p0 + ep) || positive(theta, c.p1 - ep) || positive(c.t0 + et, phi) ||
        positive(c.t1 - et, phi))
      return true;
  }
  return false;
}

// Break-function values on the 15 inner lines x 17 grid points of a cell (CellFrame), inner direction
// theta (theta_inner) or phi; returns how many lines see a sign change.
int BinCubature::break_grid(const CellFrame& f, bool theta_inner, std::vector<double>& values, long long& evals) const {
  values.resize(n_breaks_ * 15 * 17);
  const std::array<double, 17>& s_inner = f.sin_xs;
  const std::array<double, 17>& c_inner = f.cos_xs;
  int lines_cut = 0;
  for (int j = 0; j < 15; ++j) {
    const double outer = 0.5 * (f.o0 + f.o1) + 0.5 * (f.o1 - f.o0) * rule_.x[j];
    const double so = std::sin(outer), co = std::cos(outer);
    bool cut = false;
    for (std::size_t b = 0; b < n_breaks_; ++b) {
      for (int i = 0; i < 17; ++i) {
        const double v = theta_inner ? break_of_trig(b, s_inner[i], c_inner[i], so, co)
                                     : break_of_trig(b, so, co, s_inner[i], c_inner[i]);
        values[(b * 15 + j) * 17 + i] = v;
        if (i > 0 && (v >= 0) != (values[(b * 15 + j) * 17 + i - 1] >= 0)) cut = true;
      }
    }
    evals += static_cast<long long>(n_breaks_) * 17;
    lines_cut += cut;
  }
  return lines_cut;
}

// The root of break function k on an inner line between two grid points where it changes sign (values
// flo, fhi), to a bracket of 1e-14 (relative above 1): Alefeld, Potra & Shi 1995 (ACM TOMS 748), Boost.Math's
// toms748_solve.
double BinCubature::break_root(bool theta_inner, std::size_t k, double outer, double lo, double hi, double flo,
                               double fhi, long long& evals) const {
  auto f = [&](double x) {
    evals += 1;
    return break_on_line(theta_inner, k, x, outer);
  };
  auto bracket_small = [](double a, double b) { return b - a <= 1e-14 * std::max(1.0, std::abs(b)); };
  std::uintmax_t iterations = 60;
  const auto [a, b] = boost::math::tools::toms748_solve(f, lo, hi, flo, fhi, bracket_small, iterations);
  return 0.5 * (a + b);
}

// The cuts of inner line j (at `outer`): its start, then a root wherever a break function changes sign
// between two of its grid points (values in `grid`, see break_grid).
void BinCubature::cut_line(const CellFrame& f, bool theta_inner, int j, double outer, const std::vector<double>& grid,
                           LineCuts& cuts, long long& evals) const {
  cuts.at[cuts.n++] = f.i0;
  for (std::size_t b = 0; b < n_breaks_; ++b) {
    const double* v = &grid[(b * 15 + j) * 17];
    for (int i = 1; i < 17; ++i) {
      if ((v[i] >= 0) == (v[i - 1] >= 0)) continue;
      const double root = break_root(theta_inner, b, outer, f.xs[i - 1], f.xs[i], v[i - 1], v[i], evals);
      if (cuts.n < LineCuts::kMaxCuts + 1) cuts.at[cuts.n++] = root;
    }
  }
}

// Kronrod and Gauss estimates at `outer` from the sines and cosines of the 15 inner nodes of a segment of
// half-width mh (the rule's nodes in ascending order).
std::pair<double, double> BinCubature::rule_at_nodes(bool theta_inner, const double* sines, const double* cosines,
                                                     double outer, double mh, long long& evals) const {
  // The outer angle is fixed along the segment: its sine and cosine once, not at each of the 15 nodes.
  const double so = std::sin(outer), co = std::cos(outer);
  double ks = 0, gs = 0;
  for (int i = 0; i < 15; ++i) {
    const double si = sines[i], ci = cosines[i];
    const double val = theta_inner ? integrand_of_trig(si, ci, so, co) : integrand_of_trig(so, co, si, ci);
    ks += rule_.wk[i] * val;
    gs += rule_.wg[i] * val;
  }
  evals += 15;
  return {ks * mh, gs * mh};
}

// Kronrod and Gauss estimates of the integral along the inner direction from a to b (at `outer`).
std::pair<double, double> BinCubature::segment_rule(bool theta_inner, double a, double b, double outer,
                                                    long long& evals) const {
  const double mc = 0.5 * (a + b), mh = 0.5 * (b - a);
  std::array<double, 15> sines, cosines;
  for (int i = 0; i < 15; ++i) {
    const double inner = mc + mh * rule_.x[i];
    sines[i] = std::sin(inner), cosines[i] = std::cos(inner);
  }
  return rule_at_nodes(theta_inner, sines.data(), cosines.data(), outer, mh, evals);
}

// Kronrod and Gauss estimates along inner line j: in one piece, or piecewise between the cuts.
std::pair<double, double> BinCubature::line_rule(const CellFrame& f, bool theta_inner, int j, double outer,
                                                 const std::vector<double>& grid, long long& evals) const {
  LineCuts cuts;
  cut_line(f, theta_inner, j, outer, grid, cuts, evals);
  // Uncut: the whole line, whose nodes' sines and cosines the frame holds.
  if (cuts.n == 1) return rule_at_nodes(theta_inner, &f.sin_xs[1], &f.cos_xs[1], outer, 0.5 * (f.i1 - f.i0), evals);
  cuts.at[cuts.n++] = f.i1;
  std::sort(cuts.at.begin(), cuts.at.begin() + cuts.n);
  double lk = 0, lg = 0;
  for (int s = 0; s + 1 < cuts.n; ++s) {
    const double a = cuts.at[s], b = cuts.at[s + 1];
    if (!(b > a)) continue;
    const auto [ks, gs] = segment_rule(theta_inner, a, b, outer, evals);
    lk += ks;
    lg += gs;
  }
  return {lk, lg};
}

// Nested Gauss-Kronrod (K15 x K15, error against G7 x G7) over a cell, the inner integral along theta
// (theta_inner) or along phi, each inner line cut where a break function changes sign (line_rule).
void BinCubature::nested(Cell& c, const CellFrame& f, bool theta_inner, const std::vector<double>& grid,
                         long long& evals) const {
  double k = 0, g = 0, inner_err = 0, outer_err = 0;
  for (int j = 0; j < 15; ++j) {
    const double outer = f.oc + f.oh * rule_.x[j];
    const auto [lk, lg] = line_rule(f, theta_inner, j, outer, grid, evals);
    k += rule_.wk[j] * lk;
    g += rule_.wg[j] * lg;
    inner_err += rule_.wk[j] * (lk - lg);
    outer_err += (rule_.wk[j] - rule_.wg[j]) * lg;
  }
  c.value = k * f.oh;
  c.error = std::abs(k - g) * f.oh;
  // k - g = inner_err + outer_err: the inner rule's error (Kronrod against Gauss on each line) and the
  // outer rule's; where the error comes from says which side a split should halve.
  (theta_inner ? c.error_theta : c.error_phi) = std::abs(inner_err) * f.oh;
  (theta_inner ? c.error_phi : c.error_theta) = std::abs(outer_err) * f.oh;
}

// With break curves, the inner direction is the one whose lines the curves cross most often: lines
// parallel to a curve can miss it (a sliver between two nodes), lines across it cannot.
void BinCubature::evaluate(Cell& c, long long& evals) const {
  const CellFrame theta_frame(c, true, rule_);
  if (n_breaks_ == 0) {
    static const std::vector<double> none;
    nested(c, theta_frame, true, none, evals);
    return;
  }
  std::vector<double> theta_grid, phi_grid;
  const int theta_cuts = break_grid(theta_frame, true, theta_grid, evals);
  // Every theta line cut: the phi order cannot see more crossings.
  if (theta_cuts == 15) {
    nested(c, theta_frame, true, theta_grid, evals);
    return;
  }
  const CellFrame phi_frame(c, false, rule_);
  if (break_grid(phi_frame, false, phi_grid, evals) > theta_cuts) {
    nested(c, phi_frame, false, phi_grid, evals);
  } else {
    nested(c, theta_frame, true, theta_grid, evals);
  }
}

void BinCubature::add_evaluated(Refinement& r, const Cell& c) const {
  r.value += c.value;
  r.error += c.error;
  r.queue.push(c);
}

// Replaces the worst cell by its two halves along theta (along_theta) or phi.
void BinCubature::refine_worst(Refinement& r, bool along_theta) const {
  const Cell worst = r.queue.top();
  r.queue.pop();
  auto [a, b] = split_along(worst, along_theta);
  evaluate(a, r.evaluations);
  evaluate(b, r.evaluations);
  r.value += a.value + b.value - worst.value;
  r.error += a.error + b.error - worst.error;
  r.queue.push(a);
  r.queue.push(b);
}

// Phase 2: the worst cell halved along its longer side until the bin meets its tolerance, at most
// max_cells_per_bin times (the focus phase has its own budget, min_cell_size).
void BinCubature::refine_longer_sides(Refinement& r) const {
  int cells = 0;
  while (r.error > tolerance(r.value) && cells < options_.max_cells_per_bin && !r.queue.empty()) {
    const Cell& worst = r.queue.top();
    if (std::max(theta_side(worst), phi_side(worst)) <= options_.min_cell_size) break;
    refine_worst(r, theta_side(worst) >= phi_side(worst));
    ++cells;
  }
}

// Directed phase: halving the longer side resolves a lobe only as finely in its narrow direction as in its
// long one; a lobe 1e-4 long and 1e-8 wide (alpha 1e-4 at a grazing view, reflected) exhausts the budget
// above long before. Split the worst cell along the side whose rule error dominates instead, until the bin
// meets its tolerance.
void BinCubature::refine_directed(Refinement& r, int budget) const {
  for (int directed = 0; directed < budget && !r.queue.empty() && r.error > tolerance(r.value); ++directed) {
    const Cell& worst = r.queue.top();
    const bool theta_ok = theta_side(worst) > options_.min_cell_size, phi_ok = phi_side(worst) > options_.min_cell_size;
    if (!theta_ok && !phi_ok) break;
    refine_worst(r, !phi_ok || (theta_ok && worst.error_theta >= worst.error_phi));
  }
}

// The bin's value and error re-summed over its cells (the running sums accumulate cancellation).
BinResult BinCubature::resum(Refinement& r) const {
  BinResult out;
  while (!r.queue.empty()) {
    out.probability += r.queue.top().value;
    out.error += r.queue.top().error;
    r.queue.pop();
  }
  out.evaluations = r.evaluations;
  out.converged = out.error <= tolerance(out.probability);
  return out;
}

// ---- all bins ---------------------------------------------------------------------------------------

// The bins of a second pass: when the bins' error estimates add up to more than `total_error`, those that
// missed their tolerance.
std::vector<int> bins_to_integrate_again(const std::vector<BinResult>& bins, double total_error) {
  double sum = 0;
  for (const BinResult& b : bins) sum += b.error;
  std::vector<int> again;
  if (sum > total_error)
    for (int b = 0; b < int(bins.size()); ++b)
      if (!bins[b].converged) again.push_back(b);
  return again;
}

BinIntegrals sum_bins(std::vector<BinResult>& bins, int second_pass_bins) {
  BinIntegrals result;
  result.probability.resize(bins.size());
  result.second_pass_bins = second_pass_bins;
  for (std::size_t b = 0; b < bins.size(); ++b) {
    result.probability[b] = bins[b].probability;
    result.total += bins[b].probability;
    result.error_estimate += bins[b].error;
    result.evaluations += bins[b].evaluations;
  }
  return result;
}

}  // namespace

std::vector<double> DirectionBinning::integrate(const Pdf& pdf) const {
  IntegrationOptions options;
  // The lobe parameterization spreads the lobe over the whole parameter space: its own lattice is a
  // harmless focus set. A sphere binning knows nothing of the lobe; pass focus for narrow lobes.
  if (kind_ == BinningKind::lobe) options.focus = lattice_directions(4096);
  return integrate(pdf, options).probability;
}

BinIntegrals DirectionBinning::integrate(const Pdf& pdf, const IntegrationOptions& options) const {
  const BinCubature cubature(*this, pdf, options);
  FocusBuckets focus(size());
  bucket_focus(*this, options.focus, focus);
  std::vector<BinResult> bins(size());
  tbb::parallel_for(0, size(), [&](int bin) { bins[bin] = cubature.integrate_bin(bin, focus[bin], 0); });
  // Second pass: the bins that missed their tolerance integrated again from scratch with the extra focus
  // points and the directed phase. Bins that converged, and every bin when the total is small, keep their
  // first values.
  const std::vector<int> again = bins_to_integrate_again(bins, options.second_pass_total_error);
  if (!again.empty()) {
    bucket_focus(*this, options.second_pass_focus, focus);
    tbb::parallel_for(std::size_t(0), again.size(), [&](std::size_t i) {
      const int bin = again[i];
      const long long first_pass = bins[bin].evaluations;
      bins[bin] = cubature.integrate_bin(bin, focus[bin], options.max_directed_cells_per_bin);
      bins[bin].evaluations += first_pass;
    });
  }
  return sum_bins(bins, int(again.size()));
}

}  // namespace microsim
