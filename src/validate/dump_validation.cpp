#include "validate/dump_validation.h"

#include "validate/sample_io.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <span>
#include <stdexcept>
#include <vector>

namespace microsim {

namespace {

std::string frame_mistake(SampleFrame f) {
  switch (f) {
    case SampleFrame::y_up: return "in a y-up frame, (x, y, z) -> (x, -z, y)";
    case SampleFrame::z_down: return "with z flipped (the normal or the view pointing into the surface)";
    default: return "negated (the directions flipped)";
  }
}

// The claimed density loses samples (a BSDF's reflections below the horizon, a dielectric's refractions above
// it) that a renderer drops from its dump: the file holds none of them, where the test expects them.
std::string dropped_samples_hint(const ValidationReport& r, const ReferenceDistribution& ref) {
  if (ref.kept_only) return "";
  const double lost = 1.0 - ref.sphere_probability.total;
  const double expected = lost * double(r.samples);
  if (!(expected >= 5) || double(r.failed_samples) > 0.5 * expected) return "";
  return fmt::format("the claimed density loses {:.4g}% of the samples (the reflections below the horizon, a "
                     "dielectric's refractions above it): about {:.0f} expected, and the dump marks {}: a renderer's "
                     "dump that drops the samples its sampler loses? Test it with --above-horizon "
                     "(above_horizon=True) and --dropped N (dropped=N), the count it dropped",
                     100 * lost, expected, r.failed_samples);
}

// What a user does about a frame mistake: the y-up one has an option, the others are the dump's to fix.
std::string frame_fix(SampleFrame frame) {
  return frame == SampleFrame::y_up ? "give --frame y-up (Python: frame='y-up')" : "fix the dump's frame";
}

// A rejected dump with many samples where the claimed pdf is zero: which frame mistake would explain it.
std::string frame_hint(const ValidationReport& r, const DirectionSampleReader& samples,
                       const std::shared_ptr<const ReferenceDistribution>& reference, const ValidationOptions& o) {
  const double share = 100.0 * double(r.samples_where_pdf_is_zero) / double(r.samples);
  const std::optional<FrameHint> best = diagnose_sample_frame(samples, reference, o);
  if (!best)
    return fmt::format("{:.0f}% of the samples fall where the claimed pdf is zero; none of the common frame mistakes "
                       "(y-up, z flipped, negated) explains it",
                       share);
  // Read in the right frame and still rejected (for want of the samples a renderer drops): that fix too.
  std::string then;
  if (!best->report.passed) {
    then = dropped_samples_hint(best->report, *reference);
    if (then.empty() && !best->report.hints.empty()) then = best->report.hints.front();
  }
  return fmt::format("{:.0f}% of the samples fall where the claimed pdf is zero; read {} they {} (p = {:.3g}): {}{}",
                     share, frame_mistake(best->frame), best->report.passed ? "pass" : "are still rejected",
                     best->report.p_value, frame_fix(best->frame), then.empty() ? "" : "; read so, " + then);
}

// A rejected dump whose claimed density covers where its samples fall (a dielectric's, over the whole sphere) gives
// no share of samples at a zero pdf to go by: a reading in another frame is named only when it passes.
constexpr double kGrosslyRejected = 1e-12;  // the validation's p below which another frame is tried
std::string passing_frame_hint(const ValidationReport& r, const DirectionSampleReader& samples,
                               const std::shared_ptr<const ReferenceDistribution>& reference, const ValidationOptions& o) {
  if (r.passed || !(r.p_value < kGrosslyRejected)) return "";
  const std::optional<FrameHint> best = diagnose_sample_frame(samples, reference, o);
  if (!best || !best->report.passed) return "";
  return fmt::format("the samples are far from the claimed density (p = {:.3g}); read {} they pass (p = {:.3g}): {}",
                     r.p_value, frame_mistake(best->frame), best->report.p_value, frame_fix(best->frame));
}

// Reads the samples again from their first row: visit(weights, printed) for each row, its weights (one per
// channel) and a text row's printed rounding.
template <class Visit> void reread_rows(const DirectionSampleReader& samples, Visit visit) {
  DirectionSampleReader reader = samples.reopened();
  const std::size_t channels = std::size_t(reader.columns().channels());
  std::vector<Vec3<double>> rows(kSampleFileBlock);
  std::vector<double> pdfs(reader.columns().has_pdf() ? rows.size() : 0), weights(rows.size() * channels);
  std::vector<PrintedRounding> printed(rows.size());
  while (const std::size_t n = reader.read(rows, pdfs, weights, printed))
    for (std::size_t i = 0; i < n; ++i) visit(std::span<const double>(weights).subspan(i * channels, channels), printed[i]);
}

// A rejected dump with samples where the claimed pdf is zero, all of weight 0: the samples its sampler lost,
// kept as rows of weight 0 (as Mitsuba 3's sample() returns them)?
std::string zero_weight_hint(const ValidationReport& r, const DirectionSampleReader& samples) {
  if (samples.zero_weight_rows_lost() || samples.columns().channels() == 0 || r.samples_where_pdf_is_zero == 0) return "";
  std::uint64_t zero = 0;
  reread_rows(samples, [&](std::span<const double> w, const PrintedRounding&) {
    zero += std::all_of(w.begin(), w.end(), [](double x) { return x == 0; });
  });
  if (zero < r.samples_where_pdf_is_zero) return "";
  return fmt::format("{} sample(s) fall where the claimed pdf is zero and {} row(s) have weight 0: a dump that keeps "
                     "the samples its sampler loses as rows of weight 0 (as Mitsuba 3's sample() returns them)? Test "
                     "it with --lost-as-zero-weight (lost_as_zero_weight=True)",
                     r.samples_where_pdf_is_zero, zero);
}

// The narrowest width of a lobe bin near the lobe's centre: alpha / rows for normals; reflection maps a normal's
// step dm across the view's plane to 2 (wi . m) dm, so at a grazing view reflected directions are squeezed by
// 2 |wi.z| (m near the pole).
double narrowest_lobe_bin(const ValidationReport& r, const Vec3<double>& wi, int rows) {
  const double squeeze = r.domain == SampleDomain::reflected_direction ? std::min(1.0, 2 * std::abs(wi.z())) : 1.0;
  return std::min(r.alpha_x, r.alpha_y) * squeeze / rows;
}

bool binned_test_failed(const ValidationReport& r) {
  return std::any_of(r.binned.begin(), r.binned.end(),
                     [&](const BinnedTest& b) { return b.chi2.p_value < r.per_test_significance; });
}

// A binary float32 dump rejected by a chi-square test whose lobe bins are so narrow that float32's rounding of a
// direction (half a unit in the last place of a component near 1: 2^-25) is a visible share of them: the
// storage alone moves samples between bins.
std::string float32_directions_hint(const ValidationReport& r, const DirectionSampleReader& samples,
                                    const Vec3<double>& wi, int rows) {
  if (samples.storage() == "text" || !samples.is_float32() || !binned_test_failed(r)) return "";
  const double rounding = std::ldexp(1.0, -25), bin = narrowest_lobe_bin(r, wi, rows);
  if (!(rounding >= 0.05 * bin)) return "";
  return fmt::format("the directions are float32: their rounding (about {:.1e}) is {:.0f}% of the narrowest lobe bins "
                     "here (about {:.1e}: alpha {:g}{}, {} rows): the storage alone can move samples between bins; "
                     "save the directions as float64 to test the sampler itself",
                     rounding, 100 * rounding / bin, bin, std::min(r.alpha_x, r.alpha_y),
                     r.domain == SampleDomain::reflected_direction ? ", squeezed by 2 |wi.z| in reflection" : "", rows);
}

// A text dump rejected by a chi-square test whose directions are printed coarsely for the lobe's bins (about
// alpha / rows wide): the rounding alone moves samples between bins.
std::string printed_directions_hint(const ValidationReport& r, const DirectionSampleReader& samples, int rows) {
  if (samples.storage() != "text" || !binned_test_failed(r)) return "";
  // The rounding most rows show: %g drops trailing zeros, so a row printing -0.5 says nothing of the digits kept.
  std::map<double, std::uint64_t> roundings;
  std::uint64_t read = 0;
  reread_rows(samples, [&](std::span<const double>, const PrintedRounding& p) { ++roundings[p.direction], ++read; });
  double typical = 0;
  std::uint64_t seen = 0;
  for (const auto& [rounding, count] : roundings)
    if ((seen += count) * 2 >= read) {
      typical = rounding;
      break;
    }
  const double bin = std::min(r.alpha_x, r.alpha_y) / rows;
  if (!(typical >= 0.05 * bin)) return "";
  return fmt::format("the directions are printed to within {:.1e} in most rows (half a unit in their last digit), "
                     "{:.0f}% of a lobe bin's width at alpha {:g} (about alpha / rows = {:.1e}): their rounding alone "
                     "can move samples between bins; print them with more digits (%.9g)",
                     typical, 100 * typical / bin, std::min(r.alpha_x, r.alpha_y), bin);
}

// A rejected dump whose view is within 1.6 deg of the normal: a theta given in radians (at most pi / 2) where
// degrees are read? The number the user gave is the view's angle in degrees.
std::string radians_hint(const Vec3<double>& wi) {
  const double degrees = std::acos(std::clamp(std::abs(wi.z()), 0.0, 1.0)) * 180 / kPi<double>;
  if (!(degrees >= 0.05 && degrees < 1.6)) return "";
  const double meant = degrees * 180 / kPi<double>;  // v radians in degrees
  return fmt::format("the view is {:.4g} deg from the normal: theta is read in degrees; if {:.4g} was meant in "
                     "radians, give --theta {:.4g} (Python: theta={:.4g})",
                     degrees, degrees, meant, meant);
}

// What the report must say whatever the verdict: what a dump without some column could not show.
std::vector<std::string> dump_notes(const ValidationReport& r, const DirectionSampleReader& samples,
                                    const ValidationOptions& o) {
  std::vector<std::string> notes;
  if (!samples.columns().has_pdf())
    notes.push_back("the returned pdfs were not checked: the dump has no pdf column (a pdf wrong by the same factor "
                    "as f leaves the weights right)");
  if (const auto w = std::find_if(r.checks.begin(), r.checks.end(), [](const SubTest& t) { return t.name == "weight_mean"; });
      w != r.checks.end() && w->detail.find(kPdfsPrintedAsZero) != std::string::npos)
    notes.push_back("E[weight] was not tested: " + w->detail.substr(std::string("not applicable: ").size()));
  if (samples.zero_weight_rows_lost())
    notes.push_back(fmt::format("rows of weight 0 counted as the sampler's lost samples: {} of {}", r.failed_samples,
                                r.samples));
  if (samples.mirrored())
    notes.push_back("light from inside: the view and the rows mirrored in z, validated as the dielectric of index "
                    "1 / eta seen from outside");
  if (o.bsdf && o.bsdf->transmits())
    notes.push_back(fmt::format("weights tested in {}", describe(o.convention)));
  else if (o.bsdf)
    notes.push_back(fmt::format("weights tested with the {}", o.convention.masking == MaskingForm::separable
                                                                   ? "separable masking G1(wi) G1(wo)"
                                                                   : "height-correlated masking G2"));
  if (samples.columns().channels() == 0 && r.domain == SampleDomain::reflected_direction)
    notes.push_back("the weights were not checked: the dump has no weight column");
  return notes;
}

}  // namespace

std::string untested_weights_reason(const Material& bsdf, const BsdfConvention& convention) {
  if (!bsdf.transmits() || convention.normals != SampledNormals::ndf) return "";
  return "a dielectric sampling its normals from D(m) cos has heavy-tailed weights (~ 1 / m.z near the horizon), which "
         "are not tested: leave its weight columns out (mark them '-') to test its directions and pdfs, and check its "
         "eval() with check-eval";
}

ViewFromOutside seen_from_outside(const Vec3<double>& wi, const std::optional<Material>& bsdf) {
  if (!(wi.z() < 0)) return {wi, bsdf, false};
  if (!bsdf || !bsdf->transmits())
    throw std::invalid_argument("a view below the surface (theta > 90 deg) is light from inside a dielectric: give "
                                "its BSDF (--bsdf dielectric --eta ETA, bsdf='dielectric:ETA')");
  return {Vec3<double>(wi.x(), wi.y(), -wi.z()), Material::dielectric(1.0 / bsdf->eta()), true};
}

std::shared_ptr<const ReferenceDistribution> dump_reference(const DumpClaims& claims, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows, SampledNormals normals) {
  const ClaimedDensity density = file_claimed_density(claims.pdf, claims.bsdf, ggx, wi, normals);
  std::shared_ptr<const ReferenceDistribution> ref;
  if (!claims.kept_only) ref = density_reference(density, ggx, wi, rows);
  else  // a BSDF's sampling density is 0 where its samples are lost: the kept ones are its own support
    ref = claims.pdf == FilePdf::bsdf ? kept_samples_reference(density, ggx, wi, rows)
                                      : above_horizon_reference(density, ggx, wi, rows);
  if (claims.pdf != FilePdf::bsdf || !claims.bsdf || !claims.bsdf->transmits()) return ref;
  ReferenceDistribution with_eta = *ref;  // a dielectric's refractions: their half vectors need its index
  with_eta.refraction_eta = claims.bsdf->eta();
  return std::make_shared<const ReferenceDistribution>(std::move(with_eta));
}

ValidationReport validate_dump(const DirectionSampleReader& samples, std::shared_ptr<const ReferenceDistribution> reference,
                               const GGX<double>& ggx, const Vec3<double>& wi, const ValidationOptions& options,
                               bool diagnose_frame) {
  DirectionSampleReader reader = samples.reopened();
  ValidationReport r = validate_sample_file(reader, reference->domain, ggx, wi, options, reference);
  r.notes = dump_notes(r, samples, options);
  if (r.passed) return r;
  if (diagnose_frame && looks_like_a_frame_mistake(r)) r.hints.push_back(frame_hint(r, samples, reference, options));
  else if (std::string hint = diagnose_frame ? passing_frame_hint(r, samples, reference, options) : ""; !hint.empty())
    r.hints.push_back(std::move(hint));
  // Rows of weight 0 where the pdf is zero explain the lost mass better than samples dropped.
  if (std::string hint = zero_weight_hint(r, samples); !hint.empty()) r.hints.push_back(std::move(hint));
  else if (std::string dropped = dropped_samples_hint(r, *reference); !dropped.empty()) r.hints.push_back(std::move(dropped));
  if (std::string hint = radians_hint(wi); !hint.empty()) r.hints.push_back(std::move(hint));
  if (std::string hint = printed_directions_hint(r, samples, options.rows); !hint.empty()) r.hints.push_back(std::move(hint));
  if (std::string hint = float32_directions_hint(r, samples, wi, options.rows); !hint.empty()) r.hints.push_back(std::move(hint));
  return r;
}

namespace {

// Reads the first rows once, so that a malformed file is reported before the reference's cubature (which takes
// longest at many rows and for a BSDF's density); the main pass reads them again.
void check_first_rows(const DirectionSampleReader& samples) {
  constexpr std::size_t kRows = 1024;
  DirectionSampleReader reader = samples.reopened();
  std::vector<Vec3<double>> rows(kRows);
  std::vector<double> pdfs(reader.columns().has_pdf() ? kRows : 0);
  std::vector<double> weights(kRows * std::size_t(reader.columns().channels()));
  reader.read(rows, pdfs, weights);
}

// A rejected file of normals claimed as VNDF sampling's reflected directions, or the reverse (--reflected given
// or forgotten): read as the other, do they pass? Only for those two claims, all rows kept, seen from outside,
// without weights (a BSDF's weights belong to its outgoing directions).
std::string other_domain_hint(const ValidationReport& r, const DirectionSampleReader& samples, const DumpClaims& claims,
                              const GGX<double>& ggx, const Vec3<double>& wi, const ValidationOptions& options) {
  const bool normals = claims.pdf == FilePdf::vndf;
  if (r.passed || (!normals && claims.pdf != FilePdf::reflection) || claims.kept_only || claims.zero_weight_lost ||
      samples.mirrored() || options.bsdf)
    return "";
  const FilePdf other = normals ? FilePdf::reflection : FilePdf::vndf;
  const auto reference = dump_reference({other, claims.bsdf, false}, ggx, wi, options.rows, options.convention.normals);
  const ValidationReport again = validate_dump(samples, reference, ggx, wi, options, false);
  if (!again.passed) return "";
  return fmt::format("the rows are rejected as {} (p = {:.3g}) and pass as {} (p = {:.3g}): {}",
                     normals ? "normals" : "reflected directions", r.p_value,
                     normals ? "VNDF sampling's reflected directions" : "VNDF normals", again.p_value,
                     normals ? "give --reflected (Python and specs: pdf 'reflection')"
                             : "leave out --reflected (Python and specs: pdf 'vndf')");
}

}  // namespace

ValidationReport validate_dump_as_given(DirectionSampleReader& samples, const DumpClaims& claims, const GGX<double>& ggx,
                                        const Vec3<double>& view, ValidationOptions options, bool diagnose_frame) {
  if (claims.zero_weight_lost && claims.kept_only)
    throw std::invalid_argument("the lost samples are either dropped (above the horizon only) or kept as rows of "
                                "weight 0, not both");
  // Weights are f cos / pdf of a BSDF: without it they would go untested under a verdict that looks as if they were.
  if (samples.columns().channels() > 0 && !options.bsdf)
    throw std::invalid_argument(fmt::format("the dump has {} weight column(s) but no BSDF to test them against: give "
                                            "the BSDF (its material), or skip the columns", samples.columns().channels()));
  if (options.bsdf)
    if (const std::string why = untested_weights_reason(*options.bsdf, options.convention); !why.empty())
      throw std::invalid_argument(why);
  samples.set_zero_weight_rows_lost(claims.zero_weight_lost);
  check_first_rows(samples);
  const ViewFromOutside v = seen_from_outside(view, claims.bsdf);
  samples.set_mirrored(v.mirrored);
  if (options.bsdf) options.bsdf = v.bsdf;
  const auto reference =
      dump_reference({claims.pdf, v.bsdf, claims.kept_only}, ggx, v.wi, options.rows, options.convention.normals);
  ValidationReport report = validate_dump(samples, reference, ggx, v.wi, options, diagnose_frame);
  if (std::string hint = other_domain_hint(report, samples, claims, ggx, v.wi, options); !hint.empty())
    report.hints = {std::move(hint)};  // read so they pass: the other hints answer the wrong question
  report.wi = view;
  return report;
}

}  // namespace microsim
