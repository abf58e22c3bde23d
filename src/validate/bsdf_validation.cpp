#include "validate/bsdf_validation.h"

#include "validate/battery.h"
#include "validate/weight_test.h"

#include "core/block_runner.h"
#include "core/errors.h"
#include "core/random.h"
#include "stats/direction_binner.h"

#include <fmt/core.h>
#include <tbb/enumerable_thread_specific.h>

#include <chrono>
#include <stdexcept>

namespace microsim {

namespace {

// One block's samples, reused by a thread from block to block.
struct BsdfBlock {
  std::vector<Vec3<double>> directions;
  std::vector<double> pdfs, weights;
  std::vector<std::uint8_t> valid;
  void draw(const BsdfSamplerInfo& s, const Material& bsdf, const GGX<double>& ggx, const Vec3<double>& wi,
            std::uint64_t seed, std::uint64_t first, std::uint64_t end);
};

void BsdfBlock::draw(const BsdfSamplerInfo& s, const Material& bsdf, const GGX<double>& ggx, const Vec3<double>& wi,
                     std::uint64_t seed, std::uint64_t first, std::uint64_t end) {
  const std::size_t n = std::size_t(end - first);
  // A lost sample: no direction (NaN: no bin of the weight sums), weight 0, counted in the remainder cells.
  directions.assign(n, Vec3<double>::Constant(std::numeric_limits<double>::quiet_NaN()));
  pdfs.assign(n, 0.0);
  weights.assign(n, 0.0);
  valid.assign(n, 0);
  const std::complex<double> eta = sampler_index(bsdf);
  for (std::uint64_t i = first; i < end; ++i) {
    CounterRng rng(seed, i);
    const Vec3<double> u(rng.uniform(), rng.uniform(), rng.uniform());
    const BsdfSampleResult r = s.sample(ggx, eta, wi, u);
    if (!r) continue;
    const std::size_t k = std::size_t(i - first);
    directions[k] = r->wo;
    pdfs[k] = r->pdf;
    weights[k] = r->weight;
    valid[k] = 1;
  }
}

// The samples as a battery source whose stream also sums their weights per sphere bin, block by block,
// reduced in block order into `sums`.
battery::SampleSource bsdf_samples(const BsdfSamplerInfo& s, const Material& bsdf, const GGX<double>& ggx,
                                   const Vec3<double>& wi, const ValidationOptions& options,
                                   const DirectionBinning& sphere, WeightSums& sums) {
  battery::SampleSource source;
  source.name = std::string(s.name);
  source.returns_pdf = true;
  source.stream = [&s, &bsdf, ggx, wi, &options, &sphere, &sums](const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
    const BlockPlan plan{options.samples, kSampleBlock};
    const BlockRange range = selected_blocks(plan, options.blocks);
    const FastDirectionBinner binner(sphere);
    tbb::enumerable_thread_specific<BsdfBlock> buffers;
    const BlockSchedule schedule{"sampling", plan, kChunkBlocks, /*chunk_barrier=*/true};
    const BlockRunStatus status = for_each_block(
        range, options.run, schedule,
        [&](std::uint64_t b) {
          BsdfBlock& buf = buffers.local();
          buf.draw(s, bsdf, ggx, wi, options.seed, plan.first_unit(b), plan.first_unit(b) + plan.units_in(b));
          WeightSums block(1, sphere.size());
          block.add(binner, buf.directions, buf.weights, buf.directions.size());
          visit(SampleBlockView{plan.first_unit(b), buf.directions, buf.pdfs, buf.valid, {}},
                std::size_t((b - range.begin) % kChunkBlocks));
          return block;
        },
        [&](const WeightSums& block, std::uint64_t b) {
          sums.merge(block);
          const bool chunk_end = (b - range.begin + 1) % kChunkBlocks == 0 || b + 1 == range.end;
          if (chunk_end && chunk_done) chunk_done(std::size_t((b - range.begin) % kChunkBlocks) + 1);
        });
    if (status.cancelled) throw Cancelled("while sampling");
  };
  return source;
}

void check_material(const BsdfSamplerInfo& s, const Material& bsdf) {
  if (bsdf.kind() != s.material || bsdf.channels() != 1)
    throw std::invalid_argument(fmt::format("BSDF sampler '{}' samples a one-channel {}, not '{}'", s.name,
                                            s.material == MaterialKind::dielectric ? "dielectric" : "conductor",
                                            bsdf.describe()));
}

}  // namespace

Material zoo_bsdf_material(const BsdfSamplerInfo& sampler, bool from_inside) {
  if (sampler.material == MaterialKind::dielectric)
    return Material::dielectric(from_inside ? 1.0 / kZooDielectricEta : kZooDielectricEta);
  return Material::conductor({kZooConductorIor});
}

ClaimedDensity bsdf_sampling_density(const Material& bsdf, const GGX<double>& ggx, const Vec3<double>& wi_in,
                                     SampledNormals normals) {
  const Vec3<double> wi = wi_in.normalized();
  if (!bsdf.transmits())
    return {SampleDomain::reflected_direction,
            [ggx, wi, normals](const Vec3<double>& o) { return conductor_sampling_pdf(ggx, normals, wi, o); },
            {[](const Vec3<double>& o) { return o.z(); }},  // the lost reflections below the horizon
            {},
            1e-7};
  const double eta = bsdf.eta();
  const DirectionBinning lobe = DirectionBinning::lobe(ggx, wi, SampleDomain::reflected_direction, 31);
  return {SampleDomain::reflected_direction,
          [ggx, wi, eta, normals](const Vec3<double>& o) { return dielectric_sampling_pdf(ggx, normals, eta, wi, o); },
          dielectric_breaks(wi, eta), refracted_lobe_focus(lobe, wi, eta), kDielectricDensityRelTolerance};
}

ClaimedDensity file_claimed_density(FilePdf pdf, const std::optional<Material>& bsdf, const GGX<double>& ggx,
                                    const Vec3<double>& wi, SampledNormals normals) {
  if (pdf != FilePdf::bsdf) return claimed_density(pdf, ggx, wi);
  if (!bsdf) throw std::invalid_argument("the pdf 'bsdf' is the sampling density of a BSDF: give the BSDF");
  return bsdf_sampling_density(*bsdf, ggx, wi, normals);
}

BsdfReference bsdf_reference(const Material& bsdf, const BsdfConvention& convention, const GGX<double>& ggx,
                             const Vec3<double>& wi, int rows) {
  return bsdf_reference(density_reference(bsdf_sampling_density(bsdf, ggx, wi), ggx, wi, rows), bsdf, convention);
}

BsdfReference bsdf_reference(std::shared_ptr<const ReferenceDistribution> directions, const Material& bsdf,
                             const BsdfConvention& convention) {
  BsdfReference r;
  r.directions = std::move(directions);
  r.flux = expected_bin_weights(*r.directions, bsdf, convention);
  r.convention = convention;
  return r;
}

ValidationReport validate_bsdf_sampler(const BsdfSamplerInfo& sampler, const Material& bsdf, const GGX<double>& ggx,
                                       const Vec3<double>& wi_in, const ValidationOptions& options,
                                       const BsdfReference* reference) {
  const auto t0 = std::chrono::steady_clock::now();
  check_material(sampler, bsdf);
  const Vec3<double> wi = wi_in.normalized();
  require_samples_for_any_test(options.samples);
  BsdfReference own;
  if (!reference) {
    own = bsdf_reference(bsdf, options.convention, ggx, wi, options.rows);
    reference = &own;
  }
  if (!(reference->convention == options.convention))
    throw std::invalid_argument(fmt::format("validate_bsdf_sampler: the reference's flux is in {}, the options ask for {}",
                                            describe(reference->convention), describe(options.convention)));
  const ReferenceDistribution& ref = *reference->directions;
  require_samples(options.samples, ref);
  ValidationOptions o = options;
  o.precision = Precision::float64;
  WeightSums sums(1, ref.sphere.size());
  const battery::SampleSource source = bsdf_samples(sampler, bsdf, ggx, wi, o, ref.sphere, sums);
  const battery::Expectations expectations = battery::analytic_expectations(ref);
  const battery::Tally tally = battery::tally_samples(source, battery::binnings_of(expectations), o, &ref);
  std::vector<SubTest> weights = weight_checks(sums, reference->flux, double(tally.samples), ref.sphere, bsdf, o);
  ValidationReport r = battery::analytic_report(source, tally, expectations, ref, o, std::move(weights));
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace microsim
