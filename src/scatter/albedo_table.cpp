#include "scatter/albedo_table.h"
#include "core/wall_clock.h"

#include "core/parse.h"
#include "core/random.h"
#include "microfacet/bsdf.h"
#include "microgeom/assembly.h"
#include "scatter/surface_scatter.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace microsim {

std::string to_string(AlbedoModel model) {
  switch (model) {
    case AlbedoModel::analytic: return "analytic";
    case AlbedoModel::smith_walk: return "smith-walk";
    case AlbedoModel::surface: return "surface";
  }
  return "?";
}

AlbedoModel parse_albedo_model(std::string_view what, std::string_view text) {
  for (const AlbedoModel m : {AlbedoModel::analytic, AlbedoModel::smith_walk, AlbedoModel::surface})
    if (text == to_string(m)) return m;
  throw ParseError(fmt::format("{} {}: unknown model (analytic, smith-walk or surface)", what, quote_excerpt(text)));
}

namespace {

microgeom::AssemblyParams surface_params(const AlbedoTableRequest& r, double alpha) {
  microgeom::AssemblyParams p;
  p.assembly = microgeom::plain_assembly(r.ndf);
  p.alpha_x = p.alpha_y = alpha;
  p.resolution = r.resolution;
  p.seed = r.seed;
  return p;
}

void check_alphas(const std::vector<double>& alphas) {
  if (alphas.empty()) throw std::invalid_argument("albedo table: no alphas");
  for (std::size_t i = 0; i < alphas.size(); ++i) {
    const double a = alphas[i];
    if (!(a >= kMinAlbedoAlpha && a <= kMaxAlbedoAlpha))
      throw std::invalid_argument(
          fmt::format("albedo table: alpha {} outside [{}, {}]", a, kMinAlbedoAlpha, kMaxAlbedoAlpha));
    if (i > 0 && !(a > alphas[i - 1]))
      throw std::invalid_argument(
          fmt::format("albedo table: alphas must increase ({} after {})", a, alphas[i - 1]));
  }
}

void check_sampling(const AlbedoTableRequest& r) {
  if (r.paths == 0) throw std::invalid_argument("albedo table: paths per cell must be positive");
  if (r.max_order < 1 || r.max_order > kMaxOrderCap)
    throw std::invalid_argument(fmt::format("albedo table: order cap {} (expected 1 to {})", r.max_order, kMaxOrderCap));
  if (r.model != AlbedoModel::surface) return;
  for (const double a : r.alphas) {
    const microgeom::AssemblyParams p = surface_params(r, a);
    microgeom::validate(p);
    microgeom::check_supported_range(p);
  }
}

}  // namespace

void check_albedo_request(const AlbedoTableRequest& r) {
  const MaterialKind kind = r.material.kind();
  if (kind != MaterialKind::mirror && kind != MaterialKind::dielectric && kind != MaterialKind::conductor)
    throw std::invalid_argument(
        fmt::format("albedo table: material {}: mirror, conductor:ETA,K or dielectric:ETA only", r.material.describe()));
  if (kind == MaterialKind::conductor && r.material.channels() != 1)
    throw std::invalid_argument(fmt::format("albedo table: material {}: one conductor channel per table (ETA,K), not {}",
                                            r.material.describe(), r.material.channels()));
  if (r.inside && kind != MaterialKind::dielectric)
    throw std::invalid_argument("albedo table: light from inside needs a dielectric (a mirror is opaque)");
  check_alphas(r.alphas);
  if (r.walk_kernel == WalkKernel::lanes &&
      (r.model != AlbedoModel::smith_walk || !smith_walk_lanes_support(r.ndf, HeightDistribution::uniform, r.material)))
    throw std::invalid_argument(fmt::format("albedo table: the lanes walk kernel walks GGX Smith-walk tables only "
                                            "(not {} {})", to_string(r.model), to_string(r.ndf)));
  if (r.mus < kMinAlbedoMus || r.mus > kMaxAlbedoMus)
    throw std::invalid_argument(fmt::format("albedo table: {} mus (expected {} to {})", r.mus, kMinAlbedoMus, kMaxAlbedoMus));
  if (r.model == AlbedoModel::analytic) {
    if (!(r.tolerance >= 1e-13 && r.tolerance <= 1e-2))
      throw std::invalid_argument(fmt::format("albedo table: tolerance {} outside [1e-13, 1e-2]", r.tolerance));
    return;
  }
  check_sampling(r);
}

std::vector<std::string> albedo_quantity_names(AlbedoModel model, const Material& material) {
  const bool split = material.transmits();
  std::vector<std::string> names;
  if (model != AlbedoModel::analytic) {
    names.push_back("E");
    if (split) names.insert(names.end(), {"E_R", "E_T"});
  }
  names.push_back("E1");
  if (split) names.insert(names.end(), {"E1_R", "E1_T"});
  if (model != AlbedoModel::analytic) names.push_back("unfinished");
  if (model == AlbedoModel::surface) names.push_back("lost");
  return names;
}

std::string AlbedoTable::error_kind() const {
  return request.model == AlbedoModel::analytic ? "quadrature error estimate" : "standard error";
}

const AlbedoQuantity* AlbedoTable::find(std::string_view name) const {
  for (const AlbedoQuantity& q : quantities)
    if (q.name == name) return &q;
  return nullptr;
}

Estimate AlbedoTable::cell(std::string_view quantity, std::size_t alpha_index, std::size_t mu_index) const {
  const AlbedoQuantity* q = find(quantity);
  if (q == nullptr) throw std::out_of_range(fmt::format("albedo table: no quantity '{}'", quantity));
  if (alpha_index >= alphas.size() || mu_index >= mus.size())
    throw std::out_of_range(fmt::format("albedo table: no cell ({}, {})", alpha_index, mu_index));
  return q->cells[alpha_index * mus.size() + mu_index];
}

double fresnel_average(const Material& material) {
  if (material.kind() != MaterialKind::conductor)
    throw std::invalid_argument(fmt::format("F_avg: material {} is not a conductor", material.describe()));
  const MuGrid grid = gauss_legendre_mus(kFresnelAverageNodes);
  double sum = 0;
  for (std::size_t j = 0; j < grid.mus.size(); ++j)
    sum += 2 * grid.weights[j] * grid.mus[j] * fresnel_conductor(grid.mus[j], material.ior(0));
  return sum;
}

std::uint64_t albedo_cell_seed(std::uint64_t seed, std::size_t alpha_index, std::size_t mu_index) {
  CounterRng rng(seed, (std::uint64_t(alpha_index) << 32) | std::uint64_t(mu_index));
  return rng.next_u64();
}

Vec3<double> albedo_view(double mu, bool inside) {
  return {std::sqrt(std::max(0.0, 1 - mu * mu)), 0.0, inside ? -mu : mu};
}

namespace {

using Clock = std::chrono::steady_clock;

// One row's cells: per quantity (the table's order), per mu.
using RowCells = std::vector<std::vector<Estimate>>;

// E_avg = 2 sum_j w_j mu_j E_j: independent standard errors add in quadrature, error estimates linearly.
Estimate hemispherical_average(const std::vector<Estimate>& row, const MuGrid& grid, bool independent) {
  double value = 0, error = 0;
  for (std::size_t j = 0; j < row.size(); ++j) {
    const double w = 2 * grid.weights[j] * grid.mus[j];
    value += w * row[j].value;
    error += independent ? sqr(w * row[j].standard_error) : w * row[j].standard_error;
  }
  return {value, independent ? std::sqrt(error) : error};
}

void append_row(AlbedoTable& table, double alpha, const RowCells& row, const MuGrid& grid) {
  table.alphas.push_back(alpha);
  const bool independent = table.request.model != AlbedoModel::analytic;
  for (std::size_t q = 0; q < table.quantities.size(); ++q) {
    AlbedoQuantity& quantity = table.quantities[q];
    quantity.cells.insert(quantity.cells.end(), row[q].begin(), row[q].end());
    quantity.average.push_back(hemispherical_average(row[q], grid, independent));
  }
}

// The quantities of one analytic cell, in albedo_quantity_names order (E1[, E1_R, E1_T]). A Beckmann mirror's
// E(mu) in its visible slopes (beckmann_mirror_split: no sampler to invert, far cheaper than the hemisphere's).
std::vector<Estimate> analytic_cell(const AlbedoTableRequest& r, double alpha, double mu) {
  if (r.ndf == NdfKind::beckmann && r.material.kind() == MaterialKind::mirror)
    return {beckmann_mirror_split(alpha, mu, r.tolerance).unit};
  const Vec3<double> wi = albedo_view(mu, r.inside);
  const SingleScatteringAlbedo a =
      r.ndf == NdfKind::ggx ? single_scattering_albedo(GGX<double>(alpha), r.material, 0, wi, r.tolerance)
                            : single_scattering_albedo(Beckmann<double>(alpha), r.material, 0, wi, r.tolerance);
  if (!r.material.transmits()) return {a.total()};
  return {a.total(), a.reflected, a.transmitted};
}

// Every cell of an analytic row, in parallel; nullopt when cancelled before the row was complete.
std::optional<RowCells> analytic_row(const AlbedoTableRequest& r, std::size_t row, const MuGrid& grid,
                                     std::atomic<std::uint64_t>& cells_done) {
  const std::size_t n = grid.mus.size(), quantities = r.material.transmits() ? 3 : 1;
  RowCells cells(quantities, std::vector<Estimate>(n));
  std::atomic<bool> cancelled{false};
  const std::uint64_t total = std::uint64_t(r.alphas.size() * n);
  tbb::task_arena arena(r.run.threads > 0 ? r.run.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t j) {
      if (r.run.cancelled()) {
        cancelled = true;
        return;
      }
      const std::vector<Estimate> c = analytic_cell(r, r.alphas[row], grid.mus[j]);
      for (std::size_t q = 0; q < quantities; ++q) cells[q][j] = c[q];
      r.run.report("albedo table", cells_done.fetch_add(1) + 1, total);
    });
  });
  if (cancelled || r.run.cancelled()) return std::nullopt;
  return cells;
}

// The quantities of a sampled cell from its histogram (albedo_quantity_names order). The histogram's
// "reflected" bins are the upper hemisphere: from inside, what is reflected leaves downward.
std::vector<Estimate> sampled_cell(const AlbedoTableRequest& r, const ScatterHistogram& h) {
  const ScatterSide back = r.inside ? ScatterSide::transmitted : ScatterSide::reflected;
  const ScatterSide through = r.inside ? ScatterSide::reflected : ScatterSide::transmitted;
  std::vector<Estimate> c;
  for (const int order_bin : {-1, 0}) {
    c.push_back(h.albedo(0, order_bin));
    if (r.material.transmits()) {
      c.push_back(h.albedo(0, order_bin, back));
      c.push_back(h.albedo(0, order_bin, through));
    }
  }
  c.push_back(h.unfinished(0));
  if (r.model == AlbedoModel::surface) c.push_back(h.lost(0));
  return c;
}

}  // namespace

ScatterOptions albedo_cell_walk(const Vec3<double>& wi, std::uint64_t paths, std::uint64_t seed, int max_order,
                                const RunControl& run, const char* label, std::uint64_t before, std::uint64_t total) {
  ScatterOptions o;
  o.wi = wi;
  o.paths = paths;
  o.seed = seed;
  o.max_order = max_order;
  o.rows = 1;
  o.run.threads = run.threads;
  o.run.cancel = run.cancel;
  if (run.progress)
    o.run.progress = [&run, label, before, total](std::string_view, std::uint64_t done, std::uint64_t) {
      run.report(label, before + done, total);
    };
  return o;
}

namespace {

// The options of cell (row, j): its view, seed and paths; progress in paths of the whole table.
ScatterOptions cell_options(const AlbedoTableRequest& r, std::size_t row, std::size_t j, const MuGrid& grid) {
  ScatterOptions o = albedo_cell_walk(albedo_view(grid.mus[j], r.inside), r.paths, albedo_cell_seed(r.seed, row, j),
                                      r.max_order, r.run, "albedo table", (row * grid.mus.size() + j) * r.paths,
                                      r.alphas.size() * grid.mus.size() * r.paths);
  o.material = r.material;
  return o;
}

// A sampled row: `scatter(options)` per mu, in order; nullopt when a cell was cancelled.
template <class Scatter>
std::optional<RowCells> sampled_row(const AlbedoTableRequest& r, std::size_t row, const MuGrid& grid,
                                    const Scatter& scatter) {
  const std::size_t quantities = albedo_quantity_names(r.model, r.material).size();
  RowCells cells(quantities, std::vector<Estimate>(grid.mus.size()));
  for (std::size_t j = 0; j < grid.mus.size(); ++j) {
    if (r.run.cancelled()) return std::nullopt;
    const ScatterHistogram h = scatter(cell_options(r, row, j, grid));
    if (h.partial) return std::nullopt;
    const std::vector<Estimate> c = sampled_cell(r, h);
    for (std::size_t q = 0; q < quantities; ++q) cells[q][j] = c[q];
  }
  return cells;
}

// The quantities of sampled cell (row, j) from `paths` (row, options), or nullopt when cancelled.
template <class RowPaths>
std::optional<std::vector<Estimate>> sampled_cell_of(const AlbedoTableRequest& r, std::size_t row, std::size_t j,
                                                     const MuGrid& grid, const RowPaths& paths) {
  const ScatterHistogram h = paths(row, cell_options(r, row, j, grid));
  if (h.partial) return std::nullopt;
  return sampled_cell(r, h);
}

// The cells [cells.begin, cells.end) of a sampled table, each from `paths`; nullopt when cancelled.
template <class RowPaths>
std::optional<AlbedoCells> sampled_cells(const AlbedoTableRequest& r, const BlockRange& cells, std::string_view who,
                                         const RowPaths& paths) {
  const MuGrid grid = gauss_legendre_mus(r.mus);
  const std::uint64_t n = grid.mus.size();
  if (cells.begin > cells.end || cells.end > r.alphas.size() * n)
    throw std::invalid_argument(fmt::format("{}: cells {} of a table of {}", who, cells.to_string(), r.alphas.size() * n));
  AlbedoCells out;
  for (std::uint64_t c = cells.begin; c < cells.end; ++c) {
    if (r.run.cancelled()) return std::nullopt;
    std::optional<std::vector<Estimate>> cell = sampled_cell_of(r, std::size_t(c / n), std::size_t(c % n), grid, paths);
    if (!cell) return std::nullopt;
    out.push_back(std::move(*cell));
  }
  return out;
}

std::optional<RowCells> walk_row(const AlbedoTableRequest& r, std::size_t row, const MuGrid& grid) {
  const SmithMicrosurface surface{r.ndf, r.alphas[row], r.alphas[row], HeightDistribution::uniform};
  return sampled_row(r, row, grid, [&](const ScatterOptions& o) { return smith_walk_scatter(surface, o, r.walk_kernel); });
}

// A surface row: build the surface of this alpha (nullopt when cancelled during the build), then its cells.
std::optional<RowCells> surface_row(const AlbedoTableRequest& r, std::size_t row, const MuGrid& grid,
                                    double& build_seconds) {
  const Clock::time_point start = Clock::now();
  const auto progress = [&run = r.run](std::string_view, double fraction) {
    run.report("build surface", std::uint64_t(std::clamp(fraction, 0.0, 1.0) * 1000), 1000);
  };
  std::optional<microgeom::Heightfield> field;
  try {
    field.emplace(microgeom::build_assembly(surface_params(r, r.alphas[row]), nullptr, progress,
                                            [&run = r.run] { return run.cancelled(); }));
  } catch (const microgeom::BuildCancelled&) {
    return std::nullopt;
  }
  const HeightfieldScene scene(*field);
  build_seconds = seconds_since(start);
  return sampled_row(r, row, grid, [&](const ScatterOptions& o) { return scatter_on_surface(scene, o); });
}

AlbedoTable empty_table(const AlbedoTableRequest& r, const MuGrid& grid) {
  AlbedoTable t;
  t.request = r;
  t.request.run = {};
  if (r.material.kind() == MaterialKind::conductor) t.fresnel_average = fresnel_average(r.material);
  t.mus = grid.mus;
  t.mu_weights = grid.weights;
  for (const std::string& name : albedo_quantity_names(r.model, r.material)) t.quantities.push_back({name, {}, {}});
  return t;
}

}  // namespace

std::optional<AlbedoCells> walk_albedo_cells(const AlbedoTableRequest& r, const BlockRange& cells) {
  check_albedo_request(r);
  if (r.model != AlbedoModel::smith_walk) throw std::invalid_argument("walk_albedo_cells: a Smith-walk table only");
  return sampled_cells(r, cells, "walk_albedo_cells", [&r](std::size_t row, const ScatterOptions& o) {
    return smith_walk_scatter(SmithMicrosurface{r.ndf, r.alphas[row], r.alphas[row], HeightDistribution::uniform}, o,
                              r.walk_kernel);
  });
}

std::optional<AlbedoCells> surface_albedo_cells(const AlbedoTableRequest& r, const BlockRange& cells,
                                                const AlbedoSurfacePaths& paths) {
  if (r.model != AlbedoModel::surface) throw std::invalid_argument("surface_albedo_cells: a surface table only");
  AlbedoTableRequest checked = r;  // the surfaces are the caller's: its build parameters are not checked here
  checked.model = AlbedoModel::smith_walk;
  check_albedo_request(checked);
  return sampled_cells(r, cells, "surface_albedo_cells", paths);
}

AlbedoTable albedo_table_from_cells(const AlbedoTableRequest& r, const AlbedoCells& cells, double seconds) {
  const MuGrid grid = gauss_legendre_mus(r.mus);
  const std::size_t n = grid.mus.size(), quantities = albedo_quantity_names(r.model, r.material).size();
  if (cells.size() != r.alphas.size() * n)
    throw std::invalid_argument(fmt::format("albedo_table_from_cells: {} cells for a table of {}", cells.size(), r.alphas.size() * n));
  AlbedoTable table = empty_table(r, grid);
  for (std::size_t row = 0; row < r.alphas.size(); ++row) {
    RowCells rows(quantities, std::vector<Estimate>(n));
    for (std::size_t j = 0; j < n; ++j) {
      const std::vector<Estimate>& cell = cells[row * n + j];
      if (cell.size() != quantities) throw std::invalid_argument("albedo_table_from_cells: a cell of another model");
      for (std::size_t q = 0; q < quantities; ++q) rows[q][j] = cell[q];
    }
    append_row(table, r.alphas[row], rows, grid);
    table.row_seconds.push_back(seconds / double(r.alphas.size()));
  }
  table.seconds = seconds;
  return table;
}

AlbedoTable albedo_table(const AlbedoTableRequest& r, const AlbedoRowCallback& on_row) {
  check_albedo_request(r);
  const Clock::time_point start = Clock::now();
  const MuGrid grid = gauss_legendre_mus(r.mus);
  AlbedoTable table = empty_table(r, grid);
  std::atomic<std::uint64_t> cells_done{0};
  for (std::size_t row = 0; row < r.alphas.size(); ++row) {
    const Clock::time_point row_start = Clock::now();
    double build = 0;
    std::optional<RowCells> cells;
    switch (r.model) {
      case AlbedoModel::analytic: cells = analytic_row(r, row, grid, cells_done); break;
      case AlbedoModel::smith_walk: cells = walk_row(r, row, grid); break;
      case AlbedoModel::surface: cells = surface_row(r, row, grid, build); break;
    }
    if (!cells) {
      table.partial = true;
      break;
    }
    append_row(table, r.alphas[row], *cells, grid);
    table.row_seconds.push_back(seconds_since(row_start));
    if (r.model == AlbedoModel::surface) table.build_seconds.push_back(build);
    table.seconds = seconds_since(start);
    if (on_row) on_row(table, row);
  }
  table.seconds = seconds_since(start);
  return table;
}

}  // namespace microsim
