// An eval file against the Smith walk's next-event estimate (walk_eval_check.h).
#include "measure/walk_eval_check.h"
#include "stats/json_values.h"

#include <boost/math/distributions/chi_squared.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace microsim {

namespace {

double walk_index_at(const Material& m, const Vec3<double>& w) { return m.transmits() && w.z() < 0 ? m.eta() : 1.0; }

// The storage precision of the file's values (relative): text 5e-5 (4-5 printed digits), float32 and float64 their
// epsilons.
double storage_epsilon(const std::string& storage) {
  if (storage.find("text") != std::string::npos) return 5e-5;
  if (storage.find("float32") != std::string::npos) return std::numeric_limits<float>::epsilon();
  return std::numeric_limits<double>::epsilon();
}

// One row's terms: per channel the walk's f |cos wo| in the file's convention and the z of the difference.
void check_pair(WalkEvalCheckReport& r, std::vector<WalkEvalPair>& terms, const Material& m, const SmithMicrosurface& s,
                const WalkEvalCheckOptions& o, double eps, std::uint64_t row, const Vec3<double>& wi,
                const Vec3<double>& wo, const double* given) {
  if (std::abs(wi.z()) < 1e-3 || std::abs(wo.z()) < 1e-3 || (wi.z() < 0 && !m.transmits())) {
    ++r.skipped;
    return;
  }
  ScatterOptions w;
  w.wi = wi, w.material = m, w.paths = o.paths, w.seed = o.seed + row, w.max_order = o.max_order, w.run = o.run;
  const SmithWalkEval e = smith_walk_eval(s, w, wo);
  const double n = walk_index_at(m, wi) / walk_index_at(m, wo);
  const double scale = std::abs(wo.z()) * (o.convention.transport == TransportMode::radiance ? n * n : 1.0);
  for (int c = 0; c < m.channels(); ++c) {
    const Estimate walk{e.value(c).value * scale, e.value(c).standard_error * scale};
    const double var = walk.standard_error * walk.standard_error + std::pow(eps * std::abs(given[c]), 2);
    const double d = given[c] - walk.value;
    if (var == 0 && d == 0) continue;
    const double z = var > 0 ? d / std::sqrt(var) : std::copysign(INFINITY, d);
    r.statistic += z * z, ++r.dof;
    terms.push_back({row, c, wi, wo, given[c], walk, z});
  }
}

}  // namespace

WalkEvalCheckReport check_eval_file_against_walk(const std::filesystem::path& file, const EvalColumns& columns,
                                                 const Material& material, const SmithMicrosurface& surface,
                                                 const WalkEvalCheckOptions& options) {
  check_smith_microsurface(surface);
  if (material.kind() == MaterialKind::lambertian) throw std::invalid_argument("the walk check needs a mirror, a conductor or a dielectric");
  const int channels = material.channels();
  DirectionSampleReader wi_reader(file, columns.wi_columns(channels)), wo_reader(file, columns.wo_columns(channels));
  wi_reader.set_frame(options.frame);
  wo_reader.set_frame(options.frame);
  WalkEvalCheckReport r;
  r.file = file.string();
  r.storage = wi_reader.storage();
  const double eps = storage_epsilon(r.storage);
  std::vector<Vec3<double>> wi(kSampleFileBlock), wo(kSampleFileBlock);
  std::vector<double> pdfs(columns.has_pdf() ? kSampleFileBlock : 0), values(kSampleFileBlock * std::size_t(channels));
  std::vector<WalkEvalPair> terms;
  for (std::size_t n; (n = wi_reader.read(wi, pdfs, values)) > 0;) {
    if (wo_reader.read(std::span<Vec3<double>>(wo.data(), n)) != n) throw SampleFileError(file.string() + ": rows differ");
    for (std::size_t i = 0; i < n; ++i) {
      if (options.run.cancelled()) throw Cancelled("the walk eval check");
      check_pair(r, terms, material, surface, options, eps, r.rows + i, wi[i], wo[i], &values[i * std::size_t(channels)]);
    }
    r.rows += n;
  }
  r.p_value = r.dof == 0 ? 1.0
                         : (std::isfinite(r.statistic)
                                ? boost::math::cdf(boost::math::complement(boost::math::chi_squared(double(r.dof)), r.statistic))
                                : 0.0);
  std::sort(terms.begin(), terms.end(), [](const WalkEvalPair& a, const WalkEvalPair& b) { return std::abs(a.z) > std::abs(b.z); });
  terms.resize(std::min(terms.size(), options.worst));
  r.worst = std::move(terms);
  r.passed = r.dof > 0 && r.p_value >= options.level;
  return r;
}

nlohmann::json to_json(const WalkEvalCheckReport& r) {
  nlohmann::json worst = nlohmann::json::array();
  for (const WalkEvalPair& p : r.worst)
    worst.push_back({{"row", p.row}, {"channel", p.channel}, {"wi", {p.wi.x(), p.wi.y(), p.wi.z()}},
                     {"wo", {p.wo.x(), p.wo.y(), p.wo.z()}}, {"given", p.given}, {"walk", p.walk.value},
                     {"walk_standard_error", p.walk.standard_error}, {"z", finite_or_null(p.z)}});
  return {{"file", r.file}, {"storage", r.storage}, {"rows", r.rows}, {"skipped", r.skipped},
          {"chi2", finite_or_null(r.statistic)}, {"dof", r.dof},
          {"p", r.p_value}, {"verdict", r.passed ? "pass" : "fail"}, {"worst", worst}};
}

}  // namespace microsim
