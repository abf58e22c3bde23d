// validate: a renderer's eval() and pdf() checked pointwise against the exact single-scattering BSDF
// (`microsim validate --eval FILE`), the bugs a sampling test cannot see: a transmission f() off by the
// radiance factor eta^2, a reflection f() without its same-hemisphere check, G1 for G2.
//
// An eval file (.npy in any layout numpy writes, float32 or float64, or text, as sample_io.h reads) holds per
// row, in the order `columns` gives (default wi,wo,value): wi, the direction the renderer was given (the camera
// side on camera paths), wo, one value per channel of the BSDF, f(wi, wo) |cos wo| in the renderer's
// convention (transport mode, masking form: bsdf_convention.h), and optionally the pdf() of wo given wi.
//
// References: f |cos wo| of mirror_brdf, conductor_brdf, dielectric_bsdf_as (Walter et al. 2007 eq. 20-21;
// weight_test.h); the pdf of VNDF sampling (Heitz 2018) with the lobe chosen by the side of wo and Fresnel
// (reflection D_wi(h) F / (4 |wo.h|), refraction D_wi(h) (1 - F) eta^2 |wo.h| / (wi.h + eta wo.h)^2: Walter
// 2007 eq. 14, 17), backfacing microfacets 0, as pbrt-v4 (DielectricBxDF::PDF) and Mitsuba 3 (roughdielectric,
// roughconductor with visible-normal sampling) return it.
//
// Tolerance of each compared number, from the file's precision and the reference's conditioning:
//   tol = K (|ref_r - ref| + eps_r (A + 1024) |ref|) + K eps_v |ref| + h + 2 max(eps_in, eps_r, h_in) sum_k |d ref / d x_k|,
// ref in double, ref_r the same formula in the renderer's arithmetic (float32 unless said), eps_r that
// arithmetic's epsilon, A the amplification of a rounded cosine through the Fresnel term (F's square root and
// 1 - F cancel near total internal reflection, as renderers compute them) plus that of a rounded sin^2 of the
// half vector through D (2 / (alpha^2 cos^2 + sin^2): renderers compute D from cos theta_m, as pbrt-v4's
// Tan2Theta = (1 - cos^2) / cos^2, which cancels near the peak of a low roughness), 1024 epsilons for a renderer's formula
// conditioned worse than the reference's (grazing views), eps_v and eps_in the storage's of values and
// directions (binary storage; text: 0), h and h_in a text row's printed rounding (sample_io.h, PrintedRounding:
// half a unit in the last digit of the number, the coarsest of the row's direction components), the derivative over the six direction
// components by central differences (large across a kink or the horizon: the pair is then checked loosely, and
// counted), K = 16. Float32 arithmetic: about 1e-3 relative at most pairs; float64: about 2e-12.
#pragma once

#include "microfacet/bsdf_convention.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "core/run_control.h"
#include "validate/bsdf_queries.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace microsim {

// Which columns of an eval row hold what, spelled "wi,wo,value,pdf" (any order; value: one column per channel
// of the BSDF; "-" a column to skip). std::invalid_argument naming the bad item.
struct EvalColumns {
  std::vector<std::string> items;  // as given: wi, wo, value, pdf, -
  static EvalColumns parse(std::string_view spec);
  bool has_pdf() const;
  // The two sample-file column specs that read wi (with the values and pdf) and wo from the same rows.
  SampleColumns wi_columns(int channels) const;
  SampleColumns wo_columns(int channels) const;
};

struct EvalCheckOptions {
  BsdfConvention convention;
  Precision arithmetic = Precision::float32;  // the renderer's
  SampleFrame frame = SampleFrame::z_up;
  std::size_t worst = 10;  // mismatches listed
  RunControl run;
};

struct EvalMismatch {
  std::uint64_t row = 0;  // 0-based
  Vec3<double> wi, wo;
  std::string quantity;   // "value" (channel name) or "pdf"
  double given = 0, reference = 0, tolerance = 0;
  double excess() const;  // |given - reference| / tolerance (infinite for a non-finite given value)
};

struct EvalCheckReport {
  std::string file, storage;
  std::uint64_t rows = 0, values_checked = 0, pdfs_checked = 0;
  std::uint64_t value_failures = 0, pdf_failures = 0;
  std::uint64_t skipped_below = 0;  // a mirror's or conductor's wi below the surface: one- and two-sided renderers differ
  std::uint64_t loose = 0;          // pairs whose tolerance exceeds 1% of the reference (a kink, the horizon)
  double max_relative_tolerance_tight = 0;  // the largest tol / |ref| among the other pairs
  std::vector<EvalMismatch> worst;  // the largest excesses, failures first
  bool passed = false;
  std::vector<std::string> notes;
};

// f(wi, wo) |cos wo| of channel c in the renderer's convention (wi the direction it was given), in arithmetic T.
template <class T>
T bsdf_value_cos(const Material& bsdf, const GGX<T>& ggx, const BsdfConvention& convention, int c, const Vec3<T>& wi,
                 const Vec3<T>& wo);
// The pdf() of wo given wi as renderers return it (above), the normals drawn as `normals` says (VNDF sampling by
// default), in arithmetic T.
template <class T>
T renderer_pdf(const Material& bsdf, const GGX<T>& ggx, const Vec3<T>& wi, const Vec3<T>& wo,
               SampledNormals normals = SampledNormals::visible);

// Checks every row of `file`. Throws SampleFileError for a file that cannot be read as `columns` say,
// std::invalid_argument for a Lambertian BSDF.
EvalCheckReport check_eval_file(const std::filesystem::path& file, const EvalColumns& columns, const Material& bsdf,
                                const GGX<double>& ggx, const EvalCheckOptions& options);

// The same for values computed in process (a renderer's plugin): per pair its channels' values and, unless
// `pdfs` is empty, its pdf; the arithmetic's epsilon stands for the storage's. `name` names the source.
EvalCheckReport check_eval_values(std::span<const BsdfQuery> pairs, std::span<const double> values,
                                  std::span<const double> pdfs, const Material& bsdf, const GGX<double>& ggx,
                                  const EvalCheckOptions& options, const std::string& name);

nlohmann::json to_json(const EvalCheckReport& report);

}  // namespace microsim
