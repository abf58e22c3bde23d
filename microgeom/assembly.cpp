#include "microgeom/assembly.h"

#include "microgeom/ndf_match.h"
#include "microgeom/rank_order.h"

#include "core/random.h"

#include <fftw3.h>
#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <complex>
#include <cstring>
#include <memory>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <type_traits>

namespace microgeom {

namespace detail {
void radix_sort_by_high32(std::uint64_t* keys, std::uint64_t* scratch, std::size_t n) {
  // 8-bit digits: measured ~30% faster than 11-bit ones on 2M-33M keys (fewer concurrent write streams).
  constexpr int kBits = 8, kBuckets = 1 << kBits, kChunks = 32, kPasses = 32 / kBits;
  std::uint64_t* const result = keys;
  std::vector<std::array<std::size_t, kBuckets>> offsets(kChunks);
  auto chunk_begin = [&](int c) { return n * std::size_t(c) / kChunks; };
  for (int pass = 0; pass < kPasses; ++pass) {
    const int shift = 32 + kBits * pass;
    tbb::parallel_for(0, kChunks, [&](int c) {
      auto& count = offsets[c];
      count.fill(0);
      for (std::size_t k = chunk_begin(c); k < chunk_begin(c + 1); ++k) ++count[(keys[k] >> shift) & (kBuckets - 1)];
    });
    // Exclusive prefix over (bucket, chunk): chunk c's items of bucket b follow those of chunks < c.
    std::size_t running = 0;
    bool one_digit = false;  // every key has the same digit: the pass would not move anything
    for (int b = 0; b < kBuckets; ++b) {
      const std::size_t bucket_begin = running;
      for (int c = 0; c < kChunks; ++c) {
        const std::size_t count = offsets[c][b];
        offsets[c][b] = running;
        running += count;
      }
      one_digit = one_digit || running - bucket_begin == n;
    }
    if (one_digit) continue;
    tbb::parallel_for(0, kChunks, [&](int c) {
      auto& next = offsets[c];
      for (std::size_t k = chunk_begin(c); k < chunk_begin(c + 1); ++k)
        scratch[next[(keys[k] >> shift) & (kBuckets - 1)]++] = keys[k];
    });
    std::swap(keys, scratch);
  }
  if (keys != result)
    tbb::parallel_for(0, kChunks, [&](int c) {
      std::copy(keys + chunk_begin(c), keys + chunk_begin(c + 1), result + chunk_begin(c));
    });
}

void radix_sort_by_high32(std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& scratch) {
  scratch.resize(keys.size());
  radix_sort_by_high32(keys.data(), scratch.data(), keys.size());
}
}  // namespace detail

std::string_view to_string(NdfMatch m) { return m == NdfMatch::radial ? "radial" : "joint"; }

std::optional<NdfMatch> ndf_match_from_string(std::string_view name) {
  for (const NdfMatch m : {NdfMatch::radial, NdfMatch::joint})
    if (to_string(m) == name) return m;
  return std::nullopt;
}

const std::vector<AssemblyInfo>& assembly_registry() {
  static const std::vector<AssemblyInfo> registry = {
      {"smith",
       "Smith-like random assembly: a Gaussian random field whose triangle slopes are rank-matched to the GGX "
       "ellipsoid's slope law and re-integrated (iterated), so facet slopes are GGX and heights are as "
       "little tied to facet normals as a stationary single-scale field allows.",
       NdfKind::ggx},
      {"beckmann",
       "Gaussian control surface: spectral synthesis with a Gaussian spectrum exp(-|k|^2 l^2/4), rescaled to "
       "slope second moment alpha^2/2 per axis (Beckmann NDF), the case with published ray-traced results.",
       NdfKind::beckmann},
      {"mixture",
       "Gaussian scale mixture: Beckmann patches 8 correlation lengths wide, each with roughness "
       "alpha/sqrt(E), E ~ Exp(1), then slope-matched to exact GGX: same NDF, but rough and smooth regions "
       "are spatially separated so masking follows a blend of Beckmann-Smith laws.",
       NdfKind::ggx, AssemblyShaping::roughness_patches},
      {"sorted",
       "Facets sorted by height: a Gaussian field h0 mapped through a monotone G with slope factor "
       "G'(h0) = 1/sqrt(E), E = -log(1 - Phi(h0/sd)) ~ Exp(1), so slopes are exactly GGX pointwise and the "
       "steep facets sit low (in pits), then slope-matched.",
       NdfKind::ggx, AssemblyShaping::sorted_by_height},
      {"spikes",
       "The sorted surface upside down (same seed, heights negated): the same NDF with the steep facets "
       "sitting high, on spikes that mask their surroundings.",
       NdfKind::ggx, AssemblyShaping::sorted_by_height, true},
  };
  return registry;
}

const AssemblyInfo* find_assembly(std::string_view name) {
  for (const auto& a : assembly_registry())
    if (a.name == name) return &a;
  return nullptr;
}

std::string_view plain_assembly(NdfKind ndf) { return ndf == NdfKind::ggx ? "smith" : "beckmann"; }

std::string assembly_names(std::string_view separator) {
  std::string names;
  for (const auto& a : assembly_registry()) names += (names.empty() ? "" : std::string(separator)) + a.name;
  return names;
}

double default_corr_cells(int resolution) { return std::max(2.0, std::min(16.0, resolution / 16.0)); }

namespace {

bool is_power_of_two(long n) { return n > 0 && (n & (n - 1)) == 0; }

}  // namespace

void validate(const AssemblyParams& p) {
  using std::invalid_argument;
  if (!find_assembly(p.assembly))
    throw invalid_argument(fmt::format("unknown assembly '{}' (known: {})", p.assembly, assembly_names(", ")));
  for (double a : {p.alpha_x, p.alpha_y})
    if (!(std::isfinite(a) && a >= kMinAssemblyAlpha && a <= kMaxAssemblyAlpha))
      throw invalid_argument(
          fmt::format("alpha {} is out of range [{}, {}]", a, kMinAssemblyAlpha, kMaxAssemblyAlpha));
  if (!is_power_of_two(p.resolution) || p.resolution < kMinAssemblyResolution ||
      p.resolution > kMaxAssemblyResolution)
    throw invalid_argument(fmt::format("resolution {} must be a power of two in [{}, {}]", p.resolution,
                                       kMinAssemblyResolution, kMaxAssemblyResolution));
  const double l = p.corr_cells == 0 ? default_corr_cells(p.resolution) : p.corr_cells;
  if (!(std::isfinite(l) && l >= 2 && l <= p.resolution / 8.0))
    throw invalid_argument(fmt::format("correlation length {} cells must be in [2, N/8 = {}]", p.corr_cells,
                                       p.resolution / 8.0));
  if (!(std::isfinite(p.tile_size) && p.tile_size > 0))
    throw invalid_argument(fmt::format("tile size {} must be a finite number > 0", p.tile_size));
  if (p.iterations < 0 || p.iterations > 100)
    throw invalid_argument(fmt::format("iterations {} must be in [0, 100]", p.iterations));
}

double min_checked_corr_cells(int resolution) {
  return std::min(8.0, std::max(resolution >= 256 ? 4.0 : 2.0, resolution / 128.0));
}

void check_supported_range(const AssemblyParams& p) {
  const AssemblyInfo* info = find_assembly(p.assembly);
  const bool ggx = info && info->reference == NdfKind::ggx;
  if (ggx && p.resolution < kMinGgxCheckedResolution)
    throw OutsideSupportedRange(fmt::format(
        "{} at resolution {} cannot meet its NDF check: use resolution >= {} (the beckmann control works from 16)",
        p.assembly, p.resolution, kMinGgxCheckedResolution));
  const double hi = std::max(p.alpha_x, p.alpha_y), ratio = hi / std::min(p.alpha_x, p.alpha_y);
  if (ratio > kMaxCheckedAnisotropy * (1 + 1e-12)) {
    const double lo = hi / kMaxCheckedAnisotropy;  // the nearest supported pair keeping the rougher axis
    throw OutsideSupportedRange(fmt::format(
        "alpha ({:g}, {:g}): anisotropy 1:{:.4g} cannot meet the NDF check at any resolution: use max/min alpha "
        "<= {:g}, e.g. alpha ({:g}, {:g})",
        p.alpha_x, p.alpha_y, ratio, kMaxCheckedAnisotropy, p.alpha_x == hi ? hi : lo, p.alpha_y == hi ? hi : lo));
  }
  const double l = p.corr_cells == 0 ? default_corr_cells(p.resolution) : p.corr_cells;
  const double l_min = min_checked_corr_cells(p.resolution);
  const double l_max = ggx ? p.resolution / kMinGgxCorrelationLengthsPerTile : p.resolution / 8.0;
  if (l < l_min || l > l_max)
    throw OutsideSupportedRange(fmt::format(
        "correlation length {:g} cells at resolution {} cannot meet the NDF check{}: use {:g}..{:g} cells (default {:g})",
        l, p.resolution, l > l_max ? fmt::format(" for {}", p.assembly) : "", l_min, l_max,
        default_corr_cells(p.resolution)));
}

namespace {

// ---- FFTW on an N x N periodic grid (double precision) ---------------------------------------------------
// FFTW plan creation is not thread-safe: guarded by one mutex. FFTW_ESTIMATE does not touch the arrays and
// picks the plan deterministically, so results do not depend on timing.
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

class Spectral {
public:
  explicit Spectral(int n) : n_(n), nh_(n / 2 + 1) {
    real_ = fftw_alloc_real(buffer_doubles());
    spec_ = fftw_alloc_complex(std::size_t(n) * nh_);
    if (!real_ || !spec_) {
      fftw_free(real_);
      fftw_free(spec_);
      throw std::bad_alloc();
    }
    std::lock_guard lock(fftw_planner_mutex());
    forward_ = fftw_plan_dft_r2c_2d(n, n, real_, spec_, FFTW_ESTIMATE);
    inverse_ = fftw_plan_dft_c2r_2d(n, n, spec_, real_, FFTW_ESTIMATE);
  }
  ~Spectral() {
    std::lock_guard lock(fftw_planner_mutex());
    fftw_destroy_plan(forward_);
    fftw_destroy_plan(inverse_);
    fftw_free(real_);
    fftw_free(spec_);
  }
  Spectral(const Spectral&) = delete;
  Spectral& operator=(const Spectral&) = delete;

  int n() const { return n_; }
  int nh() const { return nh_; }
  // Both arrays hold N (N/2 + 1) complex numbers = N (N + 2) doubles, so either can hold a field or a
  // spectrum (the plans run on any arrays of that size and alignment: FFTW's new-array execute).
  std::size_t buffer_doubles() const { return std::size_t(n_) * std::size_t(2 * nh_); }
  double* real_data() { return real_; }
  double* spec_data() { return reinterpret_cast<double*>(spec_); }
  double& real(int i, int j) { return real_[std::size_t(j) * n_ + i]; }
  std::complex<double>* spectrum() { return reinterpret_cast<std::complex<double>*>(spec_); }
  std::complex<double>& spec(int fx, int fy) { return spectrum()[std::size_t(fy) * nh_ + fx]; }
  // Signed frequency of index f in [0, N): f or f - N.
  int signed_frequency(int f) const { return f <= n_ / 2 ? f : f - n_; }

  void forward() { fftw_execute(forward_); }
  // Inverse transform, normalised (FFTW's c2r is unnormalised); destroys the spectrum.
  void inverse() { inverse(spectrum(), real_); }
  // The same plans on other arrays of buffer_doubles() from fftw_alloc (out of place, like the plans).
  void forward(double* in, std::complex<double>* out) {
    fftw_execute_dft_r2c(forward_, in, reinterpret_cast<fftw_complex*>(out));
  }
  void inverse(std::complex<double>* in, double* out) {
    fftw_execute_dft_c2r(inverse_, reinterpret_cast<fftw_complex*>(in), out);
    const double s = 1.0 / (double(n_) * n_);
    tbb::parallel_for(std::size_t(0), std::size_t(n_), [&](std::size_t j) {
      double* row = out + j * n_;
      for (int i = 0; i < n_; ++i) row[i] *= s;
    });
  }

private:
  int n_, nh_;
  double* real_ = nullptr;
  fftw_complex* spec_ = nullptr;
  fftw_plan forward_ = nullptr, inverse_ = nullptr;
};

template <class F> void parallel_rows(int n, F&& f) {
  tbb::parallel_for(tbb::blocked_range<int>(0, n), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j != r.end(); ++j) f(j);
  });
}

// Distinct CounterRng stream families (stream = family << 40 | index).
constexpr std::uint64_t kStreamNoise = 1ull << 40;
constexpr std::uint64_t kStreamPatches = 2ull << 40;

// A periodic Gaussian random field on the N x N grid by spectral synthesis with random phases: Fourier
// amplitudes sqrt(S(k)), S(k) = exp(-(kx^2 lx^2 + ky^2 ly^2)/4) (k in radians per cell; a Gaussian
// autocorrelation exp(-x^2/lx^2 - y^2/ly^2)), and phases uniform in [0, 2 pi), Hermitian-symmetric so the
// field is real; integer wavenumbers make it exactly periodic. Fixed amplitudes make the realised slope
// second moments exactly those of the spectrum; the one-point law is Gaussian by the central limit
// theorem (a sum of ~(N/l)^2 independent random-phase waves). The phases of row fy come from
// CounterRng(seed, kStreamNoise | fy), one draw per fx. Unit-free amplitude: callers rescale or rank-match.
std::vector<double> gaussian_field(Spectral& fft, std::uint64_t seed, double lx, double ly) {
  const int n = fft.n(), nh = fft.nh();
  const double w = 2.0 * std::numbers::pi / n;
  auto amplitude = [&](int fx, int fy) {
    const double kx = w * fft.signed_frequency(fx), ky = w * fft.signed_frequency(fy);
    return std::exp(-(kx * kx * lx * lx + ky * ky * ly * ly) / 8.0);  // sqrt(S)
  };
  auto phase = [&](int fx, int fy) {
    microsim::CounterRng rng(seed, kStreamNoise | std::uint64_t(fy));
    rng.seek(std::uint64_t(fx));
    return 2.0 * std::numbers::pi * rng.uniform();
  };
  parallel_rows(n, [&](int fy) {
    for (int fx = 0; fx < nh; ++fx) {
      // Columns fx = 0 and fx = N/2 hold both k and -k: pair (fx, fy) with (fx, N - fy).
      const bool self_conjugate_column = fx == 0 || 2 * fx == n;
      std::complex<double> c;
      if (!self_conjugate_column || (fy > 0 && 2 * fy < n)) {
        c = std::polar(amplitude(fx, fy), phase(fx, fy));
      } else if (fy == 0 || 2 * fy == n) {
        c = phase(fx, fy) < std::numbers::pi ? amplitude(fx, fy) : -amplitude(fx, fy);  // real: random sign
      } else {
        c = std::conj(std::polar(amplitude(fx, n - fy), phase(fx, n - fy)));
      }
      fft.spec(fx, fy) = c;
    }
  });
  fft.spec(0, 0) = 0;  // mean 0
  fft.inverse();
  std::vector<double> h(std::size_t(n) * n);
  parallel_rows(n, [&](int j) {
    for (int i = 0; i < n; ++i) h[std::size_t(j) * n + i] = fft.real(i, j);
  });
  return h;
}

// Normalised slope of triangle t of the cell (i, row) from the heights of the row and of the next row
// (cell units, divided by (ax, ay), rounded to float): see heightfield.h for the split.
std::array<float, 2> cell_slope(const double* row, const double* next, int n, int i, int t, double ax, double ay) {
  const int i1 = i + 1 == n ? 0 : i + 1;
  const double h00 = row[i], h10 = row[i1], h01 = next[i], h11 = next[i1];
  if (t == 0) return {float((h10 - h00) / ax), float((h11 - h10) / ay)};
  return {float((h11 - h01) / ax), float((h01 - h00) / ay)};
}

// f(k, u) for every triangle k of a grid field (cell units, rows in parallel) with its slope u normalised by
// (ax, ay) (cell_slope).
template <class F>
void for_each_triangle_slope(const double* h, int n, double ax, double ay, F&& f) {
  parallel_rows(n, [&](int j) {
    const double* row = h + std::size_t(j) * n;
    const double* next = h + std::size_t(j + 1 == n ? 0 : j + 1) * n;
    for (int i = 0; i < n; ++i)
      for (int t = 0; t < 2; ++t) f(2 * (std::size_t(j) * n + i) + std::size_t(t), cell_slope(row, next, n, i, t, ax, ay));
  });
}

// Triangle slopes of a grid field (cell units), normalised by (ax, ay), into arrays (triangle id order).
void triangle_slopes(const double* h, int n, double ax, double ay, std::vector<float>& ux, std::vector<float>& uy) {
  for_each_triangle_slope(h, n, ax, ay, [&](std::size_t k, const std::array<float, 2>& u) {
    ux[k] = u[0];
    uy[k] = u[1];
  });
}

// Per-triangle slopes or targets (normalised, float) as functions of (row, next row, i, t, triangle id):
// from arrays, or computed from the heights and a stored target radius, so the radial matching keeps no
// slope arrays (4 floats per triangle) in memory.
struct StoredSlopes {
  const float *x, *y;
  std::array<float, 2> operator()(const double*, const double*, int, int, std::size_t k) const { return {x[k], y[k]}; }
};

struct HeightSlopes {
  int n;
  double ax, ay;
  std::array<float, 2> operator()(const double* row, const double* next, int i, int t, std::size_t) const {
    return cell_slope(row, next, n, i, t, ax, ay);
  }
};

// The target of the radial matching: the slope's direction with the radius of its rank (radius[k], float
// bits); zero slopes keep angle 0.
struct RadialTargets {
  HeightSlopes slope;
  const std::uint32_t* radius;
  std::array<float, 2> operator()(const double* row, const double* next, int i, int t, std::size_t k) const {
    return of_slope(slope(row, next, i, t, k), k);
  }
  std::array<float, 2> of_slope(std::array<float, 2> u, std::size_t k) const {
    const double target = std::bit_cast<float>(radius[k]);
    const double r = std::sqrt(double(u[0]) * u[0] + double(u[1]) * u[1]);
    if (r > 0) return {float(target * u[0] / r), float(target * u[1] / r)};
    return {float(target), 0.0f};
  }
};

// The three buffers of the slope matching, each N (N + 2) doubles: a real N x N field or an N x (N/2 + 1)
// half spectrum. heights: the field (the FFT's real array); aux: the target radius per triangle (float
// bits) during a matching, a spectrum during a re-integration; work: the sort buffer during a matching,
// a field then a spectrum during a re-integration (the FFT's spectrum array). With the heights they are
// the whole memory of the radial matching: 24 bytes per texel.
struct MatchBuffers {
  // The heights, if given, are moved into the FFT's real array (and freed) before aux is allocated.
  explicit MatchBuffers(Spectral& fft, std::vector<double> h = {}) : fft(fft) {
    std::copy(h.begin(), h.end(), heights());
    std::vector<double>().swap(h);
    aux_ = fftw_alloc_real(fft.buffer_doubles());
    if (!aux_) throw std::bad_alloc();
  }
  ~MatchBuffers() { fftw_free(aux_); }
  MatchBuffers(const MatchBuffers&) = delete;
  MatchBuffers& operator=(const MatchBuffers&) = delete;
  double* heights() { return fft.real_data(); }
  double* aux() { return aux_; }
  double* work() { return fft.spec_data(); }
  Spectral& fft;

private:
  double* aux_ = nullptr;
};

// Gx (the average of the two targets sharing each horizontal edge, physical slope in cell units) into
// `out`: t0 of cell (i, j) and t1 of cell (i, j - 1).
template <class Targets> void edge_targets_x(const double* h, int n, double ax, const Targets& target, double* out) {
  parallel_rows(n, [&](int j) {
    const int jm = j == 0 ? n - 1 : j - 1, j1 = j + 1 == n ? 0 : j + 1;
    const double *prev = h + std::size_t(jm) * n, *row = h + std::size_t(j) * n, *next = h + std::size_t(j1) * n;
    for (int i = 0; i < n; ++i) {
      const float a = target(row, next, i, 0, 2 * (std::size_t(j) * n + i))[0];
      const float b = target(prev, row, i, 1, 2 * (std::size_t(jm) * n + i) + 1)[0];
      out[std::size_t(j) * n + i] = 0.5 * ax * (double(a) + double(b));
    }
  });
}

// Gy (t1 of cell (i, j) and t0 of cell (i - 1, j)) over the heights, in place: a row's Gy needs the
// heights of that row and the next, so each block of rows runs in order, its next block's first row saved.
template <class Targets> void edge_targets_y_in_place(double* h, int n, double ay, const Targets& target) {
  const int blocks = std::min(n, 64);
  auto first_row = [&](int b) { return n * b / blocks; };
  std::vector<double> saved(std::size_t(blocks) * n);
  for (int b = 0; b < blocks; ++b)
    std::copy_n(h + std::size_t(first_row(b)) * n, n, saved.data() + std::size_t(b) * n);
  tbb::parallel_for(0, blocks, [&](int b) {
    std::vector<double> out(static_cast<std::size_t>(n));
    std::vector<float> t0(static_cast<std::size_t>(n));
    for (int j = first_row(b); j < first_row(b + 1); ++j) {
      double* row = h + std::size_t(j) * n;
      const double* next = j + 1 < first_row(b + 1) ? row + n : saved.data() + std::size_t((b + 1) % blocks) * n;
      for (int i = 0; i < n; ++i) t0[std::size_t(i)] = target(row, next, i, 0, 2 * (std::size_t(j) * n + i))[1];
      for (int i = 0; i < n; ++i) {
        const int im = i == 0 ? n - 1 : i - 1;
        const float a = target(row, next, i, 1, 2 * (std::size_t(j) * n + i) + 1)[1];
        out[std::size_t(i)] = 0.5 * ay * (double(a) + double(t0[std::size_t(im)]));
      }
      std::copy(out.begin(), out.end(), row);
    }
  });
}

// Periodic least-squares re-integration. Given per-triangle target slopes (normalised, tx/ty = target
// slope / alpha), finds the grid heights h (cell units, mean 0) minimising
//   sum over triangles ((sx - ax tx)/ax)^2 + ((sy - ay ty)/ay)^2.
// Each horizontal edge difference Dx(i,j) enters two triangles (t0 of cell (i,j), t1 of cell (i,j-1)), so
// the objective is 2 sum ((Dx - Gx)/ax)^2 + 2 sum ((Dy - Gy)/ay)^2 + const with Gx, Gy the averages of
// the two targets; with forward differences Dx <-> (e^{2 pi i fx/N} - 1) H in Fourier space the normal
// equations decouple per frequency:
//   H = (conj(dx) Gx / ax^2 + conj(dy) Gy / ay^2) / (|dx|^2 / ax^2 + |dy|^2 / ay^2),  H(0) = 0.
// The targets may read the heights and the aux buffer; the new heights replace the old ones.
template <class Targets> void reintegrate(MatchBuffers& buf, const Targets& target, double ax, double ay) {
  Spectral& fft = buf.fft;
  const int n = fft.n(), nh = fft.nh();
  edge_targets_x(buf.heights(), n, ax, target, buf.work());
  edge_targets_y_in_place(buf.heights(), n, ay, target);
  auto* gx = reinterpret_cast<std::complex<double>*>(buf.aux());
  auto* gy = reinterpret_cast<std::complex<double>*>(buf.work());
  fft.forward(buf.work(), gx);
  fft.forward(buf.heights(), gy);
  const double w = 2.0 * std::numbers::pi / n, wx = 1.0 / (ax * ax), wy = 1.0 / (ay * ay);
  parallel_rows(n, [&](int fy) {
    const std::complex<double> dy = std::polar(1.0, w * fy) - 1.0;
    for (int fx = 0; fx < nh; ++fx) {
      const std::complex<double> dx = std::polar(1.0, w * fx) - 1.0;
      const double denom = std::norm(dx) * wx + std::norm(dy) * wy;
      std::complex<double>& out = gy[std::size_t(fy) * nh + fx];
      if (denom <= 0) {  // only the mean (fx = fy = 0): heights are defined up to a constant
        out = 0;
        continue;
      }
      out = (std::conj(dx) * gx[std::size_t(fy) * nh + fx] * wx + std::conj(dy) * out * wy) / denom;
    }
  });
  fft.inverse(gy, buf.heights());
}

// One marginal-matching step: the target radius of every triangle (into radius[k], float bits) = the
// GGX (alpha = 1) quantile of the rank of its normalised slope radius, P(r < R) = R^2 / (1 + R^2) =>
// R = sqrt(q / (1 - q)), q = rank / (n + 1) (ranks from 1, ties broken by triangle id); the target slope
// keeps the direction (RadialTargets). With reference = beckmann (NdfMatch::joint only) the radius
// quantile is sqrt(-log(1 - q)) instead. The ranks come from detail::visit_in_rank_order with the work
// buffer as its sort buffer; a ranked triangle's entry holds its target with the top bit set meanwhile.
void match_radial(MatchBuffers& buf, double ax, double ay, NdfKind reference) {
  const int n = buf.fft.n();
  const std::size_t tris = 2 * std::size_t(n) * n;
  auto* radius = reinterpret_cast<std::uint32_t*>(buf.aux());
  for_each_triangle_slope(buf.heights(), n, ax, ay, [&](std::size_t k, const std::array<float, 2>& u) {
    const float r = std::sqrt(u[0] * u[0] + u[1] * u[1]);  // >= +0
    radius[k] = std::bit_cast<std::uint32_t>(r);
  });
  constexpr std::uint32_t kRanked = 0x80000000u;
  auto* sort_buffer = reinterpret_cast<std::uint64_t*>(buf.work());
  detail::visit_in_rank_order(
      tris, [&](std::size_t k) { return radius[k]; }, sort_buffer, buf.fft.buffer_doubles(),
      [&](std::size_t first, const std::uint64_t* keys, std::size_t count) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count), [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t s = r.begin(); s != r.end(); ++s) {
            const double q = double(first + s + 1) / double(tris + 1);
            const float target =
                float(reference == NdfKind::ggx ? std::sqrt(q / (1.0 - q)) : std::sqrt(-std::log1p(-q)));
            radius[std::uint32_t(keys[s])] = std::bit_cast<std::uint32_t>(target) | kRanked;
          }
        });
      });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tris), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) radius[k] &= ~kRanked;
  });
}

// mean |u - t| / mean |t| over triangles (deterministic: per-row partial sums added in order).
template <class Slopes, class Targets>
double slope_residual(const double* h, int n, const Slopes& slope, const Targets& target) {
  std::vector<double> diff(n), norm(n);
  parallel_rows(n, [&](int j) {
    const double* row = h + std::size_t(j) * n;
    const double* next = h + std::size_t(j + 1 == n ? 0 : j + 1) * n;
    double d = 0, s = 0;
    for (int i = 0; i < n; ++i)
      for (int t = 0; t < 2; ++t) {
        const std::size_t k = 2 * (std::size_t(j) * n + i) + std::size_t(t);
        const auto u = slope(row, next, i, t, k);
        std::array<float, 2> m;
        if constexpr (std::is_same_v<Targets, RadialTargets>) m = target.of_slope(u, k);  // the same slope
        else m = target(row, next, i, t, k);
        const double dx = double(u[0]) - m[0], dy = double(u[1]) - m[1];
        d += std::sqrt(dx * dx + dy * dy);
        s += std::sqrt(double(m[0]) * m[0] + double(m[1]) * m[1]);
      }
    diff[j] = d;
    norm[j] = s;
  });
  double d = 0, s = 0;
  for (int j = 0; j < n; ++j) {
    d += diff[j];
    s += norm[j];
  }
  return s > 0 ? d / s : 0.0;
}

// Throws BuildCancelled if the caller asked to stop.
void stop_if_cancelled(const BuildCancel& cancelled) {
  if (cancelled && cancelled()) throw BuildCancelled("surface build cancelled");
}

// The slope targets of one iteration: the radius rank-matched to GGX (angles kept), or the joint
// stratified target of the reference law (ndf_match.h, on slope arrays). match() returns the residual
// mean |u - t| / mean |t| when asked; reintegrate() then replaces the heights.
struct SlopeTargets {
  NdfMatch mode = NdfMatch::radial;
  NdfKind reference = NdfKind::ggx;
  int radial_from = -1;  // the iteration from which the radius alone is matched (-1: never switch)
  std::vector<float> ux, uy, mx, my;
  std::vector<std::uint64_t> keys, scratch;
  std::vector<std::uint16_t> stratum;

  double match(MatchBuffers& buf, double ax, double ay, bool residual) {
    const int n = buf.fft.n();
    const HeightSlopes slopes{n, ax, ay};
    if (mode == NdfMatch::radial) {
      release();
      match_radial(buf, ax, ay, reference);
      const RadialTargets targets{slopes, reinterpret_cast<const std::uint32_t*>(buf.aux())};
      return residual ? slope_residual(buf.heights(), n, slopes, targets) : 0.0;
    }
    const std::size_t tris = 2 * std::size_t(n) * n;
    ux.resize(tris), uy.resize(tris), mx.resize(tris), my.resize(tris);
    triangle_slopes(buf.heights(), n, ax, ay, ux, uy);
    match_joint_target(ux, uy, reference, mx, my, keys, scratch, stratum);
    return residual ? slope_residual(buf.heights(), n, StoredSlopes{ux.data(), uy.data()},
                                     StoredSlopes{mx.data(), my.data()})
                    : 0.0;
  }
  void reintegrate(MatchBuffers& buf, double ax, double ay) const {
    if (mode == NdfMatch::radial)
      microgeom::reintegrate(buf, RadialTargets{{buf.fft.n(), ax, ay}, reinterpret_cast<const std::uint32_t*>(buf.aux())},
                             ax, ay);
    else
      microgeom::reintegrate(buf, StoredSlopes{mx.data(), my.data()}, ax, ay);
  }
  void release() {
    for (auto* v : {&ux, &uy, &mx, &my}) std::vector<float>().swap(*v);
    std::vector<std::uint64_t>().swap(keys);
    std::vector<std::uint64_t>().swap(scratch);
    std::vector<std::uint16_t>().swap(stratum);
  }
};

// Iterated slope-marginal matching starting from h (cell units); returns the final re-integrated field.
// Alternating projections onto the GGX radius marginal (non-linear) and onto gradient fields (linear,
// least squares); the residual typically falls below 1e-3 within 8 iterations (BuildReport::residuals).
// Only the radius is matched: matching the angle as well was measured to stall the iteration at a ~5%
// residual, and the angular law of the re-integrated field relaxes back to that of the start field anyway.
// Throws BuildCancelled if the caller asked to stop.
std::vector<double> match_slopes(Spectral& fft, std::vector<double> h, double ax, double ay, int iterations,
                                 SlopeTargets& targets, BuildReport& report, const BuildProgress& progress,
                                 double progress_from, double progress_to, const BuildCancel& cancelled) {
  const std::size_t texels = h.size();
  auto buffers = std::make_unique<MatchBuffers>(fft, std::move(h));
  MatchBuffers& buf = *buffers;
  for (int it = 0; it < iterations; ++it) {
    if (progress)
      progress(fmt::format("slope matching {}/{}", it + 1, iterations),
               progress_from + (progress_to - progress_from) * it / iterations);
    stop_if_cancelled(cancelled);
    if (it == targets.radial_from) targets.mode = NdfMatch::radial;
    const double residual = targets.match(buf, ax, ay, it > 0);
    if (it > 0) report.residuals.push_back(residual);
    stop_if_cancelled(cancelled);
    targets.reintegrate(buf, ax, ay);
  }
  stop_if_cancelled(cancelled);
  if (iterations > 0) report.residuals.push_back(targets.match(buf, ax, ay, true));  // of the final field
  targets.release();
  buffers.reset();  // aux freed before the heights are copied out
  return std::vector<double>(fft.real_data(), fft.real_data() + texels);
}

// NdfMatch::joint: joint iterations, then the binned refinement of the vertex heights.
std::vector<double> match_jointly(Spectral& fft, std::vector<double> h, double ax, double ay, int iterations,
                                  NdfKind reference, BuildReport& report, const BuildProgress& progress,
                                  const BuildCancel& cancelled) {
  {
    SlopeTargets targets;
    targets.mode = NdfMatch::joint;
    targets.reference = reference;
    targets.radial_from = (iterations + 1) / 2;  // the second half radial: restores the tail quantiles (measured)
    h = match_slopes(fft, std::move(h), ax, ay, iterations, targets, report, progress, 0.05, 0.6, cancelled);
  }
  if (progress) progress("binned NDF refinement", 0.6);
  const NdfRefineReport refined = refine_binned_ndf(h, fft.n(), ax, ay, reference, NdfRefineOptions{}, cancelled);
  report.refine_sweeps = refined.sweeps;
  report.refine_moves = refined.moves;
  report.refine_objective_before = refined.objective_before;
  report.refine_objective_after = refined.objective_after;
  report.notes.push_back(fmt::format("binned NDF refinement: {} sweeps, {} vertex moves, discrepancy {:.4g} -> {:.4g}",
                                     refined.sweeps, refined.moves, refined.objective_before, refined.objective_after));
  return h;
}

// Mean over triangles of (sx/ax)^2 + (sy/ay)^2 (deterministic order).
double normalised_second_moment(const std::vector<double>& h, int n, double ax, double ay) {
  std::vector<double> rows(n);
  parallel_rows(n, [&](int j) {
    const int j1 = j + 1 == n ? 0 : j + 1;
    double s = 0;
    for (int i = 0; i < n; ++i) {
      const int i1 = i + 1 == n ? 0 : i + 1;
      // Each edge difference is shared by two triangles: the triangle mean equals the edge mean.
      const double dx = h[std::size_t(j) * n + i1] - h[std::size_t(j) * n + i];
      const double dy = h[std::size_t(j1) * n + i] - h[std::size_t(j) * n + i];
      s += dx * dx / (ax * ax) + dy * dy / (ay * ay);
    }
    rows[j] = s;
  });
  double s = 0;
  for (double r : rows) s += r;
  return s / (double(n) * n);
}

// E(t) = -log(1 - Phi(t)) for the standard normal CDF Phi, accurate in both tails: an Exp(1) variable
// when t is standard normal.
double exp_quantile_of_normal(double t) {
  if (t < 0) return -std::log1p(-0.5 * std::erfc(-t / std::numbers::sqrt2));  // 1 - Phi(t) near 1
  return -std::log(0.5 * std::erfc(t / std::numbers::sqrt2));                 // 1 - Phi(t) small
}

// The "sorted" map: h0 (a Gaussian field, rescaled so its normalised slopes have second moment 1, i.e.
// N(0, 1/2) per axis, and with height sd sigma) becomes h = sigma G(h0 / sigma), G' = 1 / sqrt(E(t)). Then
// grad h = G'(xi) grad h0 with xi = h0 / sigma standard normal and, for a stationary Gaussian field,
// independent of grad h0 at the same point: grad h = (N(0, 1/2) per axis) / sqrt(Exp(1)), the Gaussian
// scale mixture that is exactly the GGX (alpha = 1) slope law (Student-t, nu = 2). G' is large where
// E is small, i.e. for low h0: the steepest facets sit lowest. G is tabulated (trapezoid rule, step
// 1/1024 on [-9, 9], linear interpolation); the grid's secant slopes differ slightly from G' grad h0,
// which the slope matching that follows absorbs.
void sort_slopes_by_height(std::vector<double>& h, int n, double ax, double ay) {
  const double m2 = normalised_second_moment(h, n, ax, ay);
  if (!(m2 > 0)) return;
  const double scale = 1.0 / std::sqrt(m2);
  double sum2 = 0;
  for (double& z : h) {
    z *= scale;
    sum2 += z * z;
  }
  const double sigma = std::sqrt(sum2 / double(h.size()));
  if (!(sigma > 0)) return;
  constexpr double lo = -9.0, hi = 9.0, step = 1.0 / 1024;
  const int count = int((hi - lo) / step) + 1;
  std::vector<double> g(count);
  const int zero = int(-lo / step);  // G(0) = 0
  auto slope_factor = [](double t) { return 1.0 / std::sqrt(exp_quantile_of_normal(t)); };
  g[zero] = 0;
  for (int k = zero + 1; k < count; ++k)
    g[k] = g[k - 1] + 0.5 * step * (slope_factor(lo + (k - 1) * step) + slope_factor(lo + k * step));
  for (int k = zero - 1; k >= 0; --k)
    g[k] = g[k + 1] - 0.5 * step * (slope_factor(lo + (k + 1) * step) + slope_factor(lo + k * step));
  tbb::parallel_for(std::size_t(0), h.size(), [&](std::size_t k) {
    const double pos = std::clamp((h[k] / sigma - lo) / step, 0.0, double(count - 1) - 1e-9);
    const int i = int(pos);
    const double f = pos - i;
    h[k] = sigma * (g[i] + f * (g[i + 1] - g[i]));
  });
}

// The mixture's targets: the field's slopes (cell units) times the factor of their patch, normalised.
struct PatchScaledSlopes {
  int n, patches;
  double ax, ay;
  const double* scale;
  std::array<float, 2> operator()(const double* row, const double* next, int i, int t, std::size_t k) const {
    const auto u = cell_slope(row, next, n, i, t, 1.0, 1.0);
    const int j = int(k / 2 / std::size_t(n));
    const double s = scale[std::size_t(j * patches / n) * patches + std::size_t(i * patches / n)];
    return {float(u[0] * s / ax), float(u[1] * s / ay)};
  }
};

// Gaussian scale mixture: patches of 8 l cells (K x K patches of equal size); patch q scales the field's
// slopes by 1/sqrt(E_q), E_q ~ Exp(1) from CounterRng(seed, kStreamPatches | q); then re-integrate.
std::vector<double> mix_roughness_patches(Spectral& fft, std::vector<double> h, const AssemblyParams& p, double l,
                                          BuildReport& report) {
  const int n = p.resolution;
  const double ax = p.alpha_x, ay = p.alpha_y;
  const int patches = std::max(1, int(std::lround(n / (8.0 * l))));
  report.notes.push_back(fmt::format("{} x {} patches of {:.4g} cells", patches, patches, double(n) / patches));
  std::vector<double> scale(std::size_t(patches) * patches);
  for (std::size_t q = 0; q < scale.size(); ++q) {
    microsim::CounterRng rng(p.seed, kStreamPatches | q);
    // E = -log(1 - U); clamped at 1e-6 (scale <= 1000) to keep the first re-integration well scaled:
    // only the ranks of the slopes matter after matching, and clamping preserves them up to ties.
    const double e = std::max(1e-6, -std::log1p(-rng.uniform()));
    scale[q] = 1.0 / std::sqrt(e);
  }
  {
    MatchBuffers buf(fft, std::move(h));
    reintegrate(buf, PatchScaledSlopes{n, patches, ax, ay, scale.data()}, ax, ay);
  }
  return std::vector<double>(fft.real_data(), fft.real_data() + std::size_t(n) * n);
}

// Slopes of a Gaussian field are Gaussian; one scale factor sets E[(sx/ax)^2 + (sy/ay)^2] = 1, i.e.
// alpha^2/2 per axis for the isotropic-equivalent field.
void rescale_to_beckmann(std::vector<double>& h, int n, double ax, double ay) {
  const double m2 = normalised_second_moment(h, n, ax, ay);
  const double scale = m2 > 0 ? 1.0 / std::sqrt(m2) : 0.0;
  for (double& z : h) z *= scale;
}

// The heights in cell units (slopes are height differences between neighbouring vertices), as the
// registry entry says: the Gaussian field with stretched spectra (correlation length l lambda / a per
// axis, the shorter one l), shaped, then rescaled to its Beckmann NDF or slope-matched to GGX.
std::vector<double> assembly_heights(const AssemblyInfo& info, const AssemblyParams& p, double l, int iterations,
                                     BuildReport& report, const BuildProgress& progress, const BuildCancel& cancelled) {
  const int n = p.resolution;
  const double ax = p.alpha_x, ay = p.alpha_y;
  const double lambda = std::max(ax, ay), lx = l * lambda / ax, ly = l * lambda / ay;
  Spectral fft(n);
  std::vector<double> h = gaussian_field(fft, p.seed, lx, ly);
  stop_if_cancelled(cancelled);
  if (info.shaping == AssemblyShaping::roughness_patches) h = mix_roughness_patches(fft, std::move(h), p, l, report);
  if (info.shaping == AssemblyShaping::sorted_by_height) {
    sort_slopes_by_height(h, n, ax, ay);
    stop_if_cancelled(cancelled);
  }
  if (info.reference == NdfKind::beckmann) {
    rescale_to_beckmann(h, n, ax, ay);
    report.iterations = 0;
    if (p.ndf_match == NdfMatch::radial) return h;
    report.iterations = iterations;
    return match_jointly(fft, std::move(h), ax, ay, iterations, info.reference, report, progress, cancelled);
  }
  if (p.ndf_match == NdfMatch::joint) {
    h = match_jointly(fft, std::move(h), ax, ay, iterations, info.reference, report, progress, cancelled);
  } else {
    SlopeTargets targets;
    h = match_slopes(fft, std::move(h), ax, ay, iterations, targets, report, progress, 0.05, 1.0, cancelled);
  }
  if (info.upside_down)
    for (double& z : h) z = -z;
  report.iterations = iterations;
  return h;
}

}  // namespace

Heightfield build_assembly(const AssemblyParams& p, BuildReport* report_out, const BuildProgress& progress,
                           const BuildCancel& cancelled) {
  validate(p);
  BuildReport report;
  const int n = p.resolution;
  const double ax = p.alpha_x, ay = p.alpha_y;
  const double l = p.corr_cells == 0 ? default_corr_cells(n) : p.corr_cells;
  const int iterations = p.iterations == 0 ? kDefaultIterations : p.iterations;
  report.corr_cells = l;
  const AssemblyInfo* info = find_assembly(p.assembly);
  if (progress) progress("noise", 0.0);
  std::vector<double> h = assembly_heights(*info, p, l, iterations, report, progress, cancelled);

  // Physical units: slopes are dimensionless, so heights scale with the cell size. Mean 0.
  const double cell = p.tile_size / n;
  double mean = 0;
  for (double z : h) mean += z;
  mean /= double(h.size());
  std::vector<float> heights(h.size());
  for (std::size_t k = 0; k < h.size(); ++k) heights[k] = float((h[k] - mean) * cell);
  h.clear();
  h.shrink_to_fit();

  Heightfield field(n, p.tile_size, std::move(heights));
  field.metadata["assembly"] = p.assembly;
  field.metadata["alpha_x"] = fmt::format("{:.17g}", ax);
  field.metadata["alpha_y"] = fmt::format("{:.17g}", ay);
  field.metadata["seed"] = std::to_string(p.seed);
  field.metadata["corr_cells"] = fmt::format("{:.17g}", l);
  field.metadata["iterations"] = std::to_string(report.iterations);
  field.metadata["reference_ndf"] = std::string(to_string(info->reference));
  field.metadata["ndf_match"] = std::string(to_string(p.ndf_match));
  if (progress) progress("done", 1.0);
  if (report_out) *report_out = std::move(report);
  return field;
}

}  // namespace microgeom
