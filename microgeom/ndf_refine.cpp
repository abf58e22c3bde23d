// The final refinement of ndf_match.h: vertex-height moves that bring the binned NDF of a tile to the
// reference law (a greedy descent on a chi-square-like discrepancy; each move is accepted only when it
// lowers it, so the discrepancy never grows).
#include "microgeom/ndf_match.h"

#include "microgeom/surface_stats.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace microgeom {

namespace {

struct TriangleBins {
  int lobe = 0, radial = 0, sphere = 0;
  double ux = 0, uy = 0;
};

// The sphere bins of trace vndf (stats/binning.h, DirectionBinning::sphere(rows), rows odd): the normal
// m = normalize(-sx, -sy, 1) binned in `rows` bands uniform in m.z over [-1, 1] times 2 rows sectors in the
// azimuth of m. They resolve the NDF's tail, which the lobe bins lump into their last row. Reference
// probabilities: along each direction phi_u of the normalised slope the azimuth of m is fixed and the
// slope magnitude is r g(phi_u), g = |(ax cos, ay sin)|, so a band [t1, t2] of tan(theta_m) holds the
// radius range [t1 / g, t2 / g], of mass F(t2 / g) - F(t1 / g) (exact); the integral over phi_u is a
// midpoint rule with 64 nodes per sector.
class SphereNdfBins {
public:
  SphereNdfBins(int rows, double ax, double ay) : rows_(rows), ax_(ax), ay_(ay) {}
  int size() const { return rows_ * cols(); }
  int bin_of(double ux, double uy) const {
    const double sx = ax_ * ux, sy = ay_ * uy;
    const double z = 1.0 / std::sqrt(1.0 + sx * sx + sy * sy);
    const int row = std::clamp(int(std::floor((1.0 - z) / (2.0 / rows_))), 0, rows_ - 1);
    return row * cols() + column(std::atan2(-sy, -sx));
  }
  std::vector<double> probabilities(NdfKind ref) const {
    std::vector<double> p(static_cast<std::size_t>(size()), 0.0);
    const int nodes = 64 * cols();
    for (int k = 0; k < nodes; ++k) {
      const double phi = kTwoPi * (k + 0.5) / nodes, c = std::cos(phi), s = std::sin(phi);
      const double g = std::hypot(ax_ * c, ay_ * s);
      const int col = column(std::atan2(-ay_ * s, -ax_ * c));
      for (int row = 0; row < rows_; ++row) {
        const double z_hi = 1.0 - 2.0 * row / rows_, z_lo = std::max(0.0, 1.0 - 2.0 * (row + 1) / rows_);
        if (z_hi <= 0) break;
        const double mass = reference_radius_cdf(ref, tan_of(z_lo) / g) - reference_radius_cdf(ref, tan_of(z_hi) / g);
        p[static_cast<std::size_t>(row * cols() + col)] += mass / nodes;
      }
    }
    return p;
  }

private:
  int cols() const { return 2 * rows_; }
  int column(double phi) const {
    if (phi < 0) phi += kTwoPi;
    return std::clamp(int(std::floor(phi / (kTwoPi / cols()))), 0, cols() - 1);
  }
  static double tan_of(double z) { return z > 0 ? std::sqrt(std::max(0.0, 1.0 / (z * z) - 1.0)) : INFINITY; }
  int rows_;
  double ax_, ay_;
};

// 1 - F(r) of the reference radius law, accurate in the tail.
double radius_survival(NdfKind ref, double r) {
  return ref == NdfKind::ggx ? 1.0 / (1.0 + r * r) : std::exp(-r * r);
}

// Counts and first moments of the triangles in the lobe bins, counts in the radius bins, their reference
// values, and the discrepancy (see ndf_match.h).
class BinnedNdfObjective {
public:
  BinnedNdfObjective(NdfKind ref, const NdfRefineOptions& o, double triangles, double ax, double ay)
      : ref_(ref), lobe_(o.rows), sphere_(o.rows % 2 == 1 ? o.rows : o.rows + 1, ax, ay),
        radius_bins_(std::max(1, o.radius_bins)) {
    tail_bins_ = std::max(1, int(std::floor(4.0 * std::log2(triangles / (32.0 * radius_bins_)))));
    target_ = lobe_.probabilities(ref);
    moment_target_ = lobe_.first_moments(ref);
    const std::vector<double> rbar = lobe_.row_mean_radius(ref);
    moment_weight_.resize(target_.size());
    for (std::size_t b = 0; b < target_.size(); ++b) {
      target_[b] *= triangles;
      for (double& m : moment_target_[b]) m *= triangles;
      const double r = rbar[b / std::size_t(lobe_.cols())];
      moment_weight_[b] = r > 0 ? 1.0 / (r * r) : 0.0;
    }
    radial_target_.assign(std::size_t(radius_bins_ - 1 + tail_bins_), triangles / radius_bins_);
    for (int s = 0; s < tail_bins_; ++s) {
      const double a = tail_edge(s), b = s + 1 == tail_bins_ ? 0.0 : tail_edge(s + 1);
      radial_target_[std::size_t(radius_bins_ - 1 + s)] = triangles * (a - b);
    }
    sphere_target_ = sphere_.probabilities(ref);
    for (double& t : sphere_target_) t *= triangles;
    sphere_count_.assign(sphere_target_.size(), 0.0);
    count_.assign(target_.size(), 0.0);
    moment_.assign(target_.size(), {0.0, 0.0});
    radial_count_.assign(radial_target_.size(), 0.0);
  }

  TriangleBins classify(double ux, double uy) const {
    TriangleBins t{lobe_.bin_of(ux, uy), 0, sphere_.bin_of(ux, uy), ux, uy};
    const double r = std::sqrt(ux * ux + uy * uy);
    t.radial = std::min(int(reference_radius_cdf(ref_, r) * radius_bins_), radius_bins_ - 1);
    if (t.radial == radius_bins_ - 1) {  // the tail, in bins of 2^(-1/4) in 1 - F
      const double sub = std::floor(4.0 * std::log2(1.0 / (radius_bins_ * std::max(radius_survival(ref_, r), 1e-300))));
      t.radial += int(std::clamp(sub, 0.0, double(tail_bins_ - 1)));
    }
    return t;
  }

  void add(const TriangleBins& t, double sign) {
    count_[std::size_t(t.lobe)] += sign;
    moment_[std::size_t(t.lobe)][0] += sign * t.ux;
    moment_[std::size_t(t.lobe)][1] += sign * t.uy;
    radial_count_[std::size_t(t.radial)] += sign;
    sphere_count_[std::size_t(t.sphere)] += sign;
  }

  double lobe_cost(int b) const {
    const std::size_t k = std::size_t(b);
    if (!(target_[k] > 0)) return 0.0;
    const double dc = count_[k] - target_[k], dx = moment_[k][0] - moment_target_[k][0],
                 dy = moment_[k][1] - moment_target_[k][1];
    return (dc * dc + moment_weight_[k] * (dx * dx + dy * dy)) / target_[k];
  }
  double radial_cost(int b) const {
    const std::size_t k = std::size_t(b);
    const double dc = radial_count_[k] - radial_target_[k];
    return radial_target_[k] > 0 ? dc * dc / radial_target_[k] : 0.0;
  }
  // Sphere bins expecting fewer than 5 triangles weigh as if they expected 5 (the chi-square test pools them).
  double sphere_cost(int b) const {
    const std::size_t k = std::size_t(b);
    const double dc = sphere_count_[k] - sphere_target_[k];
    return dc * dc / std::max(sphere_target_[k], 5.0);
  }
  double total() const {
    double s = 0;
    for (int b = 0; b < int(sphere_target_.size()); ++b) s += sphere_cost(b);
    for (int b = 0; b < int(target_.size()); ++b) s += lobe_cost(b);
    for (int b = 0; b < int(radial_target_.size()); ++b) s += radial_cost(b);
    return s;
  }

private:
  double tail_edge(int s) const { return std::exp2(-s / 4.0) / radius_bins_; }

  NdfKind ref_;
  LobeNdfBins lobe_;
  SphereNdfBins sphere_;
  int radius_bins_, tail_bins_ = 1;
  std::vector<double> sphere_target_, sphere_count_;
  std::vector<double> target_, moment_weight_, count_, radial_target_, radial_count_;
  std::vector<std::array<double, 2>> moment_target_, moment_;
};

// The six triangles around vertex (i, j), as (cell dx, cell dy, t): see heightfield.h for the split.
constexpr int kAround[6][3] = {{0, 0, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 1}, {-1, -1, 0}, {-1, -1, 1}};

class PeriodicField {
public:
  PeriodicField(std::vector<double>& h, int n, double ax, double ay) : h_(h), n_(n), ax_(ax), ay_(ay) {}
  double& at(int i, int j) { return h_[std::size_t(wrap(j)) * n_ + wrap(i)]; }
  // Normalised slope of triangle t of cell (i, j).
  std::array<double, 2> slope(int i, int j, int t) const {
    const double h00 = get(i, j), h10 = get(i + 1, j), h01 = get(i, j + 1), h11 = get(i + 1, j + 1);
    if (t == 0) return {(h10 - h00) / ax_, (h11 - h10) / ay_};
    return {(h11 - h01) / ax_, (h01 - h00) / ay_};
  }

private:
  int wrap(int i) const { return i < 0 ? i + n_ : (i >= n_ ? i - n_ : i); }
  double get(int i, int j) const { return h_[std::size_t(wrap(j)) * n_ + wrap(i)]; }
  std::vector<double>& h_;
  int n_;
  double ax_, ay_;
};

// The distinct bins touched by two sets of triangles, and their summed cost.
double touched_cost(const BinnedNdfObjective& f, const TriangleBins* a, const TriangleBins* b) {
  int lobe[12], radial[12], sphere[12], nl = 0, nr = 0, ns = 0;
  auto note = [](int* list, int& count, int v) {
    for (int k = 0; k < count; ++k)
      if (list[k] == v) return;
    list[count++] = v;
  };
  for (int k = 0; k < 6; ++k) {
    note(lobe, nl, a[k].lobe), note(lobe, nl, b[k].lobe);
    note(radial, nr, a[k].radial), note(radial, nr, b[k].radial);
    note(sphere, ns, a[k].sphere), note(sphere, ns, b[k].sphere);
  }
  double s = 0;
  for (int k = 0; k < nl; ++k) s += f.lobe_cost(lobe[k]);
  for (int k = 0; k < nr; ++k) s += f.radial_cost(radial[k]);
  for (int k = 0; k < ns; ++k) s += f.sphere_cost(sphere[k]);
  return s;
}

void classify_around(const PeriodicField& field, const BinnedNdfObjective& f, int i, int j, TriangleBins* out) {
  for (int k = 0; k < 6; ++k) {
    const auto u = field.slope(i + kAround[k][0], j + kAround[k][1], kAround[k][2]);
    out[k] = f.classify(u[0], u[1]);
  }
}

// Tries the candidate moves of vertex (i, j) in order and keeps the first that lowers the discrepancy.
bool try_vertex(PeriodicField& field, BinnedNdfObjective& f, int i, int j, double step_height) {
  TriangleBins before[6], after[6];
  classify_around(field, f, i, j, before);
  double steepest = 1.0;
  for (const auto& t : before) steepest = std::max(steepest, std::hypot(t.ux, t.uy));
  const double s = step_height * steepest;
  double& z = field.at(i, j);
  const double z0 = z;
  for (const double d : {s, -s, 0.3 * s, -0.3 * s, 0.1 * s, -0.1 * s}) {
    z = z0 + d;
    classify_around(field, f, i, j, after);
    const double cost_before = touched_cost(f, before, after);
    for (int k = 0; k < 6; ++k) f.add(before[k], -1.0), f.add(after[k], 1.0);
    if (touched_cost(f, before, after) < cost_before - 1e-12) return true;
    for (int k = 0; k < 6; ++k) f.add(after[k], -1.0), f.add(before[k], 1.0);
  }
  z = z0;
  return false;
}

}  // namespace

NdfRefineReport refine_binned_ndf(std::vector<double>& h, int n, double ax, double ay, NdfKind ref,
                                  const NdfRefineOptions& options, const BuildCancel& cancelled) {
  PeriodicField field(h, n, ax, ay);
  BinnedNdfObjective objective(ref, options, 2.0 * n * n, ax, ay);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      for (int t = 0; t < 2; ++t) {
        const auto u = field.slope(i, j, t);
        objective.add(objective.classify(u[0], u[1]), 1.0);
      }
  NdfRefineReport report;
  report.objective_before = objective.total();
  const double step_height = options.step * std::min(ax, ay);
  for (int sweep = 0; sweep < options.max_sweeps; ++sweep) {
    if (cancelled && cancelled()) throw BuildCancelled("surface build cancelled");
    std::uint64_t moved = 0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) moved += try_vertex(field, objective, i, j, step_height) ? 1 : 0;
    report.moves += moved;
    report.sweeps = sweep + 1;
    if (double(moved) < 1e-4 * double(n) * n) break;
  }
  report.objective_after = objective.total();
  return report;
}

}  // namespace microgeom
