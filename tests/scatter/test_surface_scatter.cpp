// Tests of multiple scattering on explicit heightfields (scatter/surface_scatter.h): physical checks
// (furnace, energy conservation, Fresnel on a flat interface, reciprocity of the BRDF and the
// generalised reciprocity of the BTDF), each with a negative control that fails, and the engine (the
// documented variates, shards, threads, cancellation). Fixed seeds; the statistical checks are z tests,
// two-sided at level 1e-3 each (|z| < 3.29), with the negative controls required beyond |z| > 6.
// The first-bounce check against `trace vndf` is in test_surface_scatter_vndf.cpp.
#include "scatter/surface_scatter.h"

#include "microfacet/bsdf.h"
#include "microgeom/assembly.h"
#include "stats/binning.h"
#include "stats/direction_binner.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace microsim {
namespace {

constexpr double kZ = 3.29;        // two-sided level 1e-3
constexpr double kControlZ = 6.0;  // a negative control must fail by at least this much

microgeom::Heightfield assembled(const std::string& assembly, double alpha, int n, std::uint64_t seed) {
  microgeom::AssemblyParams p;
  p.assembly = assembly;
  p.alpha_x = p.alpha_y = alpha;
  p.resolution = n;
  p.seed = seed;
  return microgeom::build_assembly(p);
}

microgeom::Heightfield flat(int n) { return microgeom::Heightfield(n, 1.0, std::vector<float>(std::size_t(n) * n, 0.0f)); }

ScatterOptions options(const Vec3<double>& wi, const Material& m, std::uint64_t paths, std::uint64_t seed = 1) {
  ScatterOptions o;
  o.wi = wi;
  o.material = m;
  o.paths = paths;
  o.seed = seed;
  o.rows = 4;
  return o;
}

// Light from inside the solid, theta degrees from the downward normal.
Vec3<double> from_inside(double theta_deg, double phi_deg) {
  Vec3<double> w = direction_from_degrees(theta_deg, phi_deg);
  w.z() = -w.z();
  return w;
}

double z_score(const Estimate& e, double expected) { return (e.value - expected) / e.standard_error; }

// ---- the furnace and energy conservation --------------------------------------------------------------

// What is wrong with a furnace run (empty: nothing): every path leaves upward, none is lost or left
// unfinished, the total albedo is exactly 1 (every weight is 1 and the sums are exact: no tolerance).
std::string furnace_failures(const ScatterHistogram& h, const SurfaceScatterDiagnostics& d) {
  std::string f;
  if (h.albedo(0, -1).value != 1.0) f += " albedo " + std::to_string(h.albedo(0, -1).value);
  if (h.albedo(0, -1, ScatterSide::transmitted).value != 0.0) f += " transmitted";
  if (d.lost() != 0 || h.lost(0).value != 0.0) f += " lost " + std::to_string(d.lost());
  if (d.unfinished != 0) f += " unfinished " + std::to_string(d.unfinished);
  return f;
}

// A mirror heightfield reflects everything: alpha 1 (orders 2+ carry a fifth of the light at 60 deg),
// GGX (`smith`) and Beckmann assemblies. Negative controls: the same surface with the order cap at 1
// (unfinished paths) and as a conductor (F < 1) both fail.
TEST(SurfaceScatter, MirrorFurnaceReflectsEverything) {
  for (const char* assembly : {"smith", "beckmann"}) {
    const auto field = assembled(assembly, 1.0, 64, 3);
    const HeightfieldScene scene(field);
    ScatterOptions o = options(direction_from_degrees(60.0, 30.0), Material::mirror(), 40000);
    SurfaceScatterDiagnostics d;
    const ScatterHistogram h = scatter_on_surface(scene, o, &d);
    EXPECT_EQ(furnace_failures(h, d), "") << assembly;
    EXPECT_GT(h.albedo(0, 1).value, 0.05) << assembly;  // multiple scattering is exercised
    EXPECT_GT(h.albedo(0, 2).value, 0.005) << assembly;
    EXPECT_EQ(d.paths, o.paths);
    EXPECT_EQ(d.traced, d.paths + d.facet_events);

    o.max_order = 1;
    const ScatterHistogram capped = scatter_on_surface(scene, o, &d);
    EXPECT_NE(furnace_failures(capped, d), "");
    EXPECT_GT(capped.unfinished(0).value, 0.05);  // the weight left at the cap is reported
    EXPECT_EQ(capped.albedo(0, -1).value + capped.unfinished(0).value, 1.0);
    o.max_order = kDefaultMaxOrder;
    o.material = Material::conductor({{0.2, 3.9}});
    const ScatterHistogram gold = scatter_on_surface(scene, o, &d);
    EXPECT_NE(furnace_failures(gold, d), "");
    EXPECT_LT(z_score(gold.albedo(0, -1), 1.0), -kControlZ);
  }
}

// A white Lambertian facet material (albedo 1) conserves energy as well: every path leaves upward or stops
// at the order cap (a few random walks down the deepest, near-vertical pits of the assembly do), with
// albedo + unfinished = 1 exactly and nothing lost. Negative control: a grey one (albedo 0.9).
TEST(SurfaceScatter, WhiteLambertianFurnace) {
  const auto field = assembled("smith", 0.5, 64, 5);
  const HeightfieldScene scene(field);
  SurfaceScatterDiagnostics d;
  const auto run = [&](double albedo) {
    return scatter_on_surface(scene, options(direction_from_degrees(40.0, 10.0), Material::lambertian(albedo), 20000), &d);
  };
  const ScatterHistogram h = run(1.0);
  EXPECT_EQ(d.lost(), 0u);
  EXPECT_EQ(h.albedo(0, -1).value + h.unfinished(0).value, 1.0);
  EXPECT_EQ(h.albedo(0, -1, ScatterSide::transmitted).value, 0.0);
  EXPECT_LT(h.unfinished(0).value, 1e-3);
  EXPECT_GT(h.albedo(0, 1).value, 0.05);
  const ScatterHistogram grey = run(0.9);
  EXPECT_LT((grey.albedo(0, -1).value + grey.unfinished(0).value - 1.0) / grey.albedo(0, -1).standard_error, -kControlZ);
}

// A rough dielectric conserves energy, lit from outside and from inside (below and beyond the critical
// angle, 41.8 deg): R + T + unfinished = 1 exactly (weights 1, exact sums), nothing lost, the order cap
// almost never reached, both sides and orders 2+ exercised. Negative control: with the order cap at 1,
// R + T falls short of 1 by far more than its standard error.
TEST(SurfaceScatter, DielectricConservesEnergyFromBothSides) {
  const auto field = assembled("smith", 0.5, 64, 7);
  const HeightfieldScene scene(field);
  for (const Vec3<double>& wi : {direction_from_degrees(50.0, 20.0), from_inside(30.0, 20.0), from_inside(60.0, 200.0)}) {
    ScatterOptions o = options(wi, Material::dielectric(1.5), 30000);
    SurfaceScatterDiagnostics d;
    const ScatterHistogram h = scatter_on_surface(scene, o, &d);
    const double r = h.albedo(0, -1, ScatterSide::reflected).value, t = h.albedo(0, -1, ScatterSide::transmitted).value;
    EXPECT_EQ(d.lost(), 0u) << wi.transpose();
    EXPECT_EQ(h.lost(0).value, 0.0);
    EXPECT_NEAR(r + t + h.unfinished(0).value, 1.0, 1e-15);
    EXPECT_LT(h.unfinished(0).value, 1e-3);
    EXPECT_GT(std::min(r, t), 0.02) << wi.transpose();
    EXPECT_GT(h.albedo(0, 1).value, 0.01) << wi.transpose();  // order 2
    EXPECT_GT(d.transmitted + d.reflected, o.paths - o.paths / 1000);

    o.max_order = 1;
    const ScatterHistogram capped = scatter_on_surface(scene, o, &d);
    const Estimate rt = capped.albedo(0, -1);
    EXPECT_LT(z_score(rt, 1.0), -kControlZ) << wi.transpose();
  }
}

// ---- a flat interface: exact Fresnel ------------------------------------------------------------------

// The order-1 weight of channel 0 on one side.
double side_weight(const ScatterHistogram& h, ScatterSide side) {
  double w = 0;
  for (std::size_t b = 0; b < h.bins(); ++b)
    if (h.is_reflection_bin(b) == (side == ScatterSide::reflected)) w += h.histogram(0, 0).weight(b);
  return w;
}

// A flat heightfield is a plane interface: every path has one event, and the fraction reflected is the
// Fresnel reflectance (a binomial proportion; z test at 1e-3), all of it in the specular bin; the
// transmitted light leaves in the refracted direction's bin. From inside beyond the critical angle,
// everything is reflected. A conductor's weight is its Fresnel reflectance, per channel, exactly.
// Negative control: the reflectance of the inverted relative index (the inside/outside mix-up) is
// rejected.
TEST(SurfaceScatter, FlatInterfaceFollowsFresnel) {
  const auto field = flat(16);
  const HeightfieldScene scene(field);
  const DirectionBinning bins = DirectionBinning::hemispheres(4);
  const double eta = 1.5;
  struct Case {
    Vec3<double> wi;
    double eta_ratio;  // n_transmitted / n_incident
  };
  for (const Case& c : {Case{direction_from_degrees(60.0, 30.0), eta}, Case{from_inside(30.0, 100.0), 1.0 / eta},
                        Case{from_inside(50.0, 100.0), 1.0 / eta}}) {
    SurfaceScatterDiagnostics d;
    const ScatterHistogram h = scatter_on_surface(scene, options(c.wi, Material::dielectric(eta), 40000), &d);
    const double cos_i = std::abs(c.wi.z());
    const double f = fresnel_dielectric(cos_i, c.eta_ratio);
    // Reflected light leaves on wi's side.
    const ScatterSide back = c.wi.z() > 0 ? ScatterSide::reflected : ScatterSide::transmitted;
    const ScatterSide through = c.wi.z() > 0 ? ScatterSide::transmitted : ScatterSide::reflected;
    const Estimate r = h.albedo(0, 0, back);
    EXPECT_EQ(d.facet_events, d.paths);
    const Vec3<double> n = c.wi.z() > 0 ? Vec3<double>::UnitZ() : Vec3<double>(-Vec3<double>::UnitZ());
    const Vec3<double> mirror = reflect(c.wi, n);
    EXPECT_EQ(h.histogram(0, 0).weight(std::size_t(*bins.bin_of(mirror))), side_weight(h, back));
    if (f == 1.0) {
      EXPECT_EQ(r.value, 1.0);  // total internal reflection
      continue;
    }
    const double sd = std::sqrt(f * (1 - f) / double(h.paths()));
    EXPECT_LT(std::abs(r.value - f) / sd, kZ) << c.wi.transpose() << " R " << r.value << " F " << f;
    const double wrong = fresnel_dielectric(cos_i, 1.0 / c.eta_ratio);
    EXPECT_GT(std::abs(r.value - wrong) / sd, kControlZ) << "negative control";
    Vec3<double> refracted;
    ASSERT_TRUE(refract(c.wi, n, c.eta_ratio, refracted));
    EXPECT_EQ(h.histogram(0, 0).weight(std::size_t(*bins.bin_of(refracted))), side_weight(h, through));
  }
  const Material gold = Material::conductor({{0.18, 3.4}, {0.42, 2.35}, {1.37, 1.77}});
  const Vec3<double> wi = direction_from_degrees(70.0, 45.0);
  const ScatterHistogram h = scatter_on_surface(scene, options(wi, gold, 5000));
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(h.albedo(c, 0).value, fresnel_conductor(wi.z(), gold.ior(c)), 1e-15) << c;
    EXPECT_LT(h.albedo(c, 0).standard_error, 1e-9);
  }
}

// ---- reciprocity -----------------------------------------------------------------------------------------

// A bin of the hemispheres binning: z in [z_lo, z_hi], phi in [phi_lo, phi_hi] (radians).
struct Region {
  double z_lo, z_hi, phi_lo, phi_hi;
  // Projected solid angle, the integral of |z| over the region.
  double projected() const { return 0.5 * (phi_hi - phi_lo) * std::abs(z_hi * z_hi - z_lo * z_lo); }
  // A direction of the region with density proportional to |z| (z^2 uniform).
  Vec3<double> cosine_direction(double u0, double u1) const {
    const double z2 = z_lo * z_lo + u0 * (z_hi * z_hi - z_lo * z_lo);
    const double z = std::copysign(std::sqrt(z2), z_lo + z_hi), phi = phi_lo + u1 * (phi_hi - phi_lo);
    const double s = std::sqrt(std::max(0.0, 1.0 - z2));
    return {s * std::cos(phi), s * std::sin(phi), z};
  }
};

Region region_of(const DirectionBinning& b, int bin) {
  const BinBounds r = b.bounds(bin);
  constexpr double rad = kPi<double> / 180.0;
  return {std::cos(r.theta_max_deg * rad), std::cos(r.theta_min_deg * rad), r.phi_min_deg * rad, r.phi_max_deg * rad};
}

// The flux from light spread over region `from` (cosine-weighted, `runs` directions stratified in z)
// into bin `to`, per unit incident flux, per order bin (0 .. 4) and for all orders (index 5), each with
// its standard error from the spread of the runs (each run its own direction and seed). Its expectation
// is (1 / P(from)) integral over from x to of f(wi, wo) |wi.z| |wo.z|, P the projected solid angle.
std::array<Estimate, kScatterOrderBins + 1> flux(const HeightfieldScene& scene, const Material& m, const Region& from,
                                                 int to, int runs, std::uint64_t paths, std::uint64_t seed) {
  CounterRng rng(seed, 1000);
  std::array<std::vector<double>, kScatterOrderBins + 1> v;
  for (int k = 0; k < runs; ++k) {
    const Vec3<double> wi = from.cosine_direction((k + rng.uniform()) / runs, rng.uniform());
    const ScatterHistogram h = scatter_on_surface(scene, options(wi, m, paths, seed + std::uint64_t(k)));
    double total = 0;
    for (int ob = 0; ob < kScatterOrderBins; ++ob) {
      const double w = h.histogram(0, ob).weight(std::size_t(to)) / double(h.paths());
      v[std::size_t(ob)].push_back(w);
      total += w;
    }
    v[kScatterOrderBins].push_back(total);
  }
  std::array<Estimate, kScatterOrderBins + 1> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    double mean = 0, var = 0;
    for (double x : v[i]) mean += x / runs;
    for (double x : v[i]) var += (x - mean) * (x - mean) / (runs - 1);
    out[i] = {mean, std::sqrt(var / runs)};
  }
  return out;
}

// z of a - b for two independent estimates scaled by sa and sb.
double difference_z(const Estimate& a, double sa, const Estimate& b, double sb) {
  return (sa * a.value - sb * b.value) / std::hypot(sa * a.standard_error, sb * b.standard_error);
}

// The measured BRDF of a rough mirror heightfield is reciprocal, order by order (the reversed path meets
// the same facets in reverse order): light spread over bin A into bin B against light over B into A,
// P(A) flux(A -> B) = P(B) flux(B -> A) (both sides: the integral of f(wi, wo) |wi.z| |wo.z| over A x B).
// A (theta 41-60 deg) and B (60-76 deg, the opposite azimuth: the lobe's forward part). Negative control:
// B into A', A turned by 180 degrees (back-scatter, a different pair), is rejected.
TEST(SurfaceScatter, MirrorBrdfIsReciprocal) {
  const auto field = assembled("smith", 1.0, 64, 11);
  const HeightfieldScene scene(field);
  const DirectionBinning bins = DirectionBinning::hemispheres(4);
  const int cols = bins.cols(), a = 1 * cols + 0, b = 2 * cols + cols / 2, a_turned = 1 * cols + cols / 2;
  const Region ra = region_of(bins, a), rb = region_of(bins, b);
  const Material mirror = Material::mirror();
  const auto ab = flux(scene, mirror, ra, b, 48, 4096, 100), ba = flux(scene, mirror, rb, a, 48, 4096, 200);
  for (std::size_t k : {std::size_t(0), std::size_t(1), std::size_t(kScatterOrderBins)}) {  // orders 1, 2, all
    EXPECT_GT(ab[k].value, 10 * ab[k].standard_error) << k;  // enough light for the test to mean something
    EXPECT_LT(std::abs(difference_z(ab[k], ra.projected(), ba[k], rb.projected())), kZ)
        << "order bin " << k << ": " << ab[k].value << " +- " << ab[k].standard_error << " vs " << ba[k].value << " +- "
        << ba[k].standard_error;
  }
  const auto turned = flux(scene, mirror, rb, a_turned, 48, 4096, 200);
  EXPECT_GT(std::abs(difference_z(ab[kScatterOrderBins], ra.projected(), turned[kScatterOrderBins], rb.projected())),
            kControlZ);
}

// The dielectric BTDF obeys f(wi, wo) / eta_o^2 = f(wo, wi) / eta_i^2 (Veach 1997, "Robust Monte Carlo
// Methods for Light Transport Simulation", thesis, section 5.2; Walter et al. 2007, eq. 21): light
// spread over the upper bin A transmitted into the lower bin B (around the refracted direction) against
// light from inside over B transmitted into A: P(A) flux(A -> B) / eta^2 = P(B) flux(B -> A), order by
// order and in total. Negative control: without the eta^2 (plain reciprocity), rejected.
TEST(SurfaceScatter, DielectricBtdfObeysGeneralisedReciprocity) {
  const auto field = assembled("smith", 0.5, 64, 13);
  const HeightfieldScene scene(field);
  const DirectionBinning bins = DirectionBinning::hemispheres(4);
  const int cols = bins.cols(), a = 1 * cols + 0, b = 7 * cols + cols / 2;
  const Region ra = region_of(bins, a), rb = region_of(bins, b);
  const double eta = 1.5;
  const Material glass = Material::dielectric(eta);
  const auto ab = flux(scene, glass, ra, b, 32, 4096, 300), ba = flux(scene, glass, rb, a, 32, 4096, 400);
  for (std::size_t k : {std::size_t(0), std::size_t(1), std::size_t(kScatterOrderBins)}) {  // orders 1, 2, all
    EXPECT_GT(ab[k].value, 10 * ab[k].standard_error) << k;
    EXPECT_LT(std::abs(difference_z(ab[k], ra.projected() / (eta * eta), ba[k], rb.projected())), kZ)
        << "order bin " << k << ": " << ab[k].value << " +- " << ab[k].standard_error << " vs " << ba[k].value << " +- "
        << ba[k].standard_error;
  }
  EXPECT_GT(std::abs(difference_z(ab[kScatterOrderBins], ra.projected(), ba[kScatterOrderBins], rb.projected())),
            kControlZ);
}

// ---- the engine ------------------------------------------------------------------------------------------

// scatter_on_surface is the documented loop over SurfacePathTracer, path by path: path i of block b has
// its origin from draws 2i, 2i + 1 of CounterRng(seed, b) and its events from path_event_stream.
TEST(SurfaceScatter, IsTheDocumentedPathLoop) {
  const auto field = assembled("smith", 0.5, 32, 17);
  const HeightfieldScene scene(field);
  const ScatterOptions o = options(direction_from_degrees(45.0, 60.0), Material::dielectric(1.3), 2 * kPathsPerBlock + 99, 23);
  const ScatterHistogram h = scatter_on_surface(scene, o);
  ScatterHistogram expected = empty_scatter_histogram(o, kSurfaceScatterProducer, surface_scatter_measurement(field, o));
  const SurfacePathTracer tracer(scene, o.material, o.wi, o.max_order);
  const DirectionBinning bins = DirectionBinning::hemispheres(o.rows);
  SurfacePath path;
  for (std::uint64_t block = 0; block < 3; ++block) {
    CounterRng origins(o.seed, block);
    const std::uint64_t n = BlockPlan{o.paths, kPathsPerBlock}.units_in(block);
    for (std::uint64_t i = 0; i < n; ++i) {
      const double u0 = origins.uniform(), u1 = origins.uniform();
      tracer.trace(tracer.origin(u0, u1), path_event_stream(o.seed, block, i, kPathsPerBlock), path);
      const std::span<const double> w(path.weight.data(), 1);
      if (path.end == PathEnd::reflected || path.end == PathEnd::transmitted) {
        expected.add_escaped(path.order, std::size_t(*bins.bin_of(path.direction)), w);
      } else if (path.end == PathEnd::unfinished) {
        expected.add_unfinished(w);
      } else {
        expected.add_lost(w);
      }
    }
    expected.add_launched(n);
  }
  EXPECT_TRUE(h == expected);
  EXPECT_GT(h.albedo(0, -1, ScatterSide::transmitted).value, 0.5);
}

// Shards merge into the unsharded run bit for bit, whatever the thread count; the provenance records
// the blocks. A cancelled run is the completed prefix of its blocks, marked partial.
TEST(SurfaceScatter, ShardsThreadsAndCancellation) {
  const auto field = assembled("smith", 0.7, 32, 19);
  const HeightfieldScene scene(field);
  ScatterOptions o = options(direction_from_degrees(70.0, 10.0), Material::conductor({{0.2, 3.9}, {1.1, 2.0}}),
                             5 * kPathsPerBlock + 7, 29);
  o.run.threads = 2;
  SurfaceScatterDiagnostics dw;
  const ScatterHistogram whole = scatter_on_surface(scene, o, &dw);
  EXPECT_EQ(whole.provenance.blocks, (BlockRange{0, 6}));
  EXPECT_EQ(whole.provenance.total_blocks, 6u);
  EXPECT_FALSE(whole.partial);
  EXPECT_EQ(whole.paths(), o.paths);

  o.run.threads = 1;
  EXPECT_TRUE(scatter_on_surface(scene, o) == whole);
  ScatterHistogram merged;
  SurfaceScatterDiagnostics dm;
  for (const BlockRange& r : {BlockRange{0, 2}, BlockRange{2, 3}, BlockRange{3, 6}}) {
    o.blocks = r;
    SurfaceScatterDiagnostics d;
    const ScatterHistogram part = scatter_on_surface(scene, o, &d);
    EXPECT_EQ(part.provenance.blocks, r);
    EXPECT_NO_THROW(part.provenance.check_same_run(whole.provenance));
    if (r.begin == 0) merged = part;
    else merged.merge(part);
    dm.add(d);
  }
  merged.provenance = whole.provenance;
  EXPECT_TRUE(merged == whole);
  EXPECT_TRUE(dm == dw);

  // Cancelled after the first block reported: the result is the shard [0, k) it completed.
  CancelToken token;
  o.blocks.reset();
  o.run.cancel = &token;
  o.run.progress = [&](std::string_view, std::uint64_t, std::uint64_t) { token.cancel(); };
  const ScatterHistogram cut = scatter_on_surface(scene, o);
  EXPECT_TRUE(cut.partial);
  ASSERT_GT(cut.provenance.blocks.end, 0u);
  ASSERT_LT(cut.provenance.blocks.end, 6u);
  o.run.cancel = nullptr;
  o.run.progress = nullptr;
  o.blocks = cut.provenance.blocks;
  ScatterHistogram prefix = scatter_on_surface(scene, o);
  prefix.partial = true;
  EXPECT_TRUE(prefix == cut);
  // Another surface or view is another run.
  o.wi = direction_from_degrees(70.0, 11.0);
  EXPECT_ANY_THROW(scatter_on_surface(scene, o).provenance.check_same_run(whole.provenance));
}

TEST(SurfaceScatter, RejectsBadOptions) {
  const auto field = flat(16);
  const HeightfieldScene scene(field);
  EXPECT_THROW(scatter_on_surface(scene, options(from_inside(30.0, 0.0), Material::mirror(), 10)), std::invalid_argument);
  ScatterOptions o = options(direction_from_degrees(30.0, 0.0), Material::mirror(), 10);
  o.max_order = 0;
  EXPECT_THROW(scatter_on_surface(scene, o), std::invalid_argument);
  o.max_order = 1;
  o.wi = Vec3<double>(0.5, 0.5, 0.0);
  EXPECT_THROW(scatter_on_surface(scene, o), std::invalid_argument);
}

}  // namespace
}  // namespace microsim
