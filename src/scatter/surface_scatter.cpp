// scatter: multiple scattering on an explicit heightfield, into a per-order histogram (see
// surface_scatter.h).
#include "scatter/surface_scatter.h"

#include "stats/direction_binner.h"
#include "trace/embree.h"

#include <fmt/core.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <span>
#include <vector>

namespace microsim {

void SurfaceScatterDiagnostics::add(const SurfaceScatterDiagnostics& o) {
  paths += o.paths;
  traced += o.traced;
  segments += o.segments;
  facet_events += o.facet_events;
  edge_grazes += o.edge_grazes;
  reflected += o.reflected;
  transmitted += o.transmitted;
  unfinished += o.unfinished;
  unbinned += o.unbinned;
  leaked += o.leaked;
  crossed_unseen += o.crossed_unseen;
  unresolved += o.unresolved;
  wrong_side += o.wrong_side;
}

static_assert(std::uint64_t(kMaxOrderCap) <= kMaxPathEvents, "a path's event draws must not reach the next path's");

namespace {

// FNV-1a (Fowler, Noll, Vo) over the bits of the heights: tells two surfaces of one size apart.
std::uint64_t heights_hash(const microgeom::Heightfield& field) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const float z : field.heights()) {
    h ^= std::bit_cast<std::uint32_t>(z);
    h *= 0x100000001b3ULL;
  }
  return h;
}

// What one path added to the histogram (its weights are BlockResult::weights[i channels ...]).
struct PathRecord {
  PathEnd end = PathEnd::lost;
  int order = 0;
  int bin = -1;  // reflected, transmitted: the bin, or -1 (unbinned)
};

// One block's paths, in order, and its diagnostics: the reduction adds them to the result (add_block),
// so a block in flight holds a few bytes per path, not a histogram.
struct BlockResult {
  std::vector<PathRecord> paths;
  std::vector<double> weights;
  SurfaceScatterDiagnostics diagnostics;
};

// One run: the path tracer and the binning of the outgoing directions (the upper hemisphere's bins first).
class SurfaceScatterRun {
public:
  SurfaceScatterRun(const HeightfieldScene& scene, const ScatterOptions& options)
      : tracer_(scene, options.material, options.wi, options.max_order),
        binning_(DirectionBinning::hemispheres(options.rows)), binner_(binning_),
        plan_{options.paths, kPathsPerBlock}, seed_(options.seed), channels_(options.material.channels()) {}
  SurfaceScatterRun(const SurfaceScatterRun&) = delete;
  SurfaceScatterRun& operator=(const SurfaceScatterRun&) = delete;

  const BlockPlan& plan() const { return plan_; }
  BlockResult run_block(std::uint64_t block) const;
  void add_block(const BlockResult& r, ScatterHistogram& h) const;

private:
  PathRecord tally(const SurfacePath& path, SurfaceScatterDiagnostics& d) const;

  SurfacePathTracer tracer_;
  DirectionBinning binning_;
  FastDirectionBinner binner_;      // points to binning_
  BlockPlan plan_;
  std::uint64_t seed_;
  int channels_;
};

BlockResult SurfaceScatterRun::run_block(std::uint64_t block) const {
  embree::FlushDenormalsScope ftz;
  BlockResult r;
  const std::uint64_t n = plan_.units_in(block);
  r.paths.resize(n);
  r.weights.resize(n * std::uint64_t(channels_));
  tracer_.trace_block(seed_, block, n, kPathsPerBlock, [&](std::uint64_t i, const SurfacePath& path) {
    r.paths[i] = tally(path, r.diagnostics);
    std::copy(path.weight.begin(), path.weight.begin() + channels_, r.weights.begin() + std::ptrdiff_t(i * std::uint64_t(channels_)));
  });
  r.diagnostics.paths = n;
  return r;
}

PathRecord SurfaceScatterRun::tally(const SurfacePath& path, SurfaceScatterDiagnostics& d) const {
  d.traced += std::uint64_t(path.traced);
  d.segments += std::uint64_t(path.segments);
  d.facet_events += std::uint64_t(path.order);
  d.edge_grazes += std::uint64_t(path.edge_grazes);
  PathRecord record{path.end, path.order, -1};
  switch (path.end) {
    case PathEnd::reflected:
    case PathEnd::transmitted: {
      const bool up = path.end == PathEnd::reflected;
      ++(up ? d.reflected : d.transmitted);
      const int bin = binner_(path.direction);
      // A direction binned on the other side (within rounding of the horizon) is kept, unbinned.
      if (bin >= 0 && (bin < binning_.size() / 2) == up) record.bin = bin;  // rows from the top
      else ++d.unbinned;
      return record;
    }
    case PathEnd::unfinished: ++d.unfinished; return record;
    case PathEnd::lost: break;
  }
  switch (path.loss) {
    case PathLoss::leaked: ++d.leaked; break;
    case PathLoss::crossed_unseen: ++d.crossed_unseen; break;
    case PathLoss::unresolved: ++d.unresolved; break;
    case PathLoss::wrong_side:
    case PathLoss::none: ++d.wrong_side; break;
  }
  return record;
}

void SurfaceScatterRun::add_block(const BlockResult& r, ScatterHistogram& h) const {
  h.add_launched(r.paths.size());
  for (std::size_t i = 0; i < r.paths.size(); ++i) {
    const PathRecord& p = r.paths[i];
    const std::span<const double> w(r.weights.data() + i * std::size_t(channels_), std::size_t(channels_));
    switch (p.end) {
      case PathEnd::reflected:
      case PathEnd::transmitted:
        if (p.bin >= 0) h.add_escaped(p.order, std::size_t(p.bin), w);
        else h.add_escaped_unbinned(p.order, w);
        break;
      case PathEnd::unfinished: h.add_unfinished(w); break;
      case PathEnd::lost: h.add_lost(w); break;
    }
  }
}

}  // namespace

std::string surface_scatter_measurement(const microgeom::Heightfield& field, const ScatterOptions& o) {
  return fmt::format("surface {}x{} tile {:.17g} heights {:016x}; wi {:.17g},{:.17g},{:.17g}; material {}; "
                     "max_order {}; rows {}; paths {}",
                     field.resolution(), field.resolution(), field.tile_size(), heights_hash(field), o.wi.x(), o.wi.y(),
                     o.wi.z(), o.material.describe(), o.max_order, o.rows, o.paths);
}

ScatterHistogram scatter_on_surface(const HeightfieldScene& scene, const ScatterOptions& options,
                                    SurfaceScatterDiagnostics* diagnostics) {
  ScatterHistogram result =
      empty_scatter_histogram(options, kSurfaceScatterProducer, surface_scatter_measurement(scene.field(), options));
  const SurfaceScatterRun run(scene, options);
  SurfaceScatterDiagnostics total;
  const BlockRunStatus status = for_each_block(
      selected_blocks(run.plan(), options.blocks), options.run,
      {"scatter surface", run.plan()},
      [&](std::uint64_t block) { return run.run_block(block); },
      [&](BlockResult&& r, std::uint64_t) {
        run.add_block(r, result);
        total.add(r.diagnostics);
      });
  result.provenance.blocks = status.done;
  result.partial = status.cancelled;
  if (diagnostics) *diagnostics = total;
  return result;
}

ScatterHistogram scatter_on_surface(const microgeom::Heightfield& field, const ScatterOptions& options,
                                    SurfaceScatterDiagnostics* diagnostics) {
  check_scatter_options(options);
  const HeightfieldScene scene(field);
  return scatter_on_surface(scene, options, diagnostics);
}

}  // namespace microsim
