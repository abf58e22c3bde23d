// One BSDF's consistency with itself from a sample dump and an eval file (bsdf_file_check.h).
#include "measure/bsdf_file_check.h"

#include "measure/bsdf_self_check.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <cmath>

namespace microsim {

namespace {

constexpr double kFileConsistency = 1e-3;  // relative, as the battery's

struct FileRows {
  battery::ViewSamples s;
  std::vector<double> eval_value, eval_pdf;  // per row: channels values, one pdf
};

FileRows read_rows(const std::filesystem::path& dump, const SampleColumns& dc, const std::filesystem::path& eval,
                   const EvalColumns& ec, const Vec3<double>& view, const BsdfFileCheckOptions& o) {
  const int c = dc.channels();
  if (!dc.has_pdf() || c < 1) throw std::invalid_argument("--columns: the dump needs x, y, z, pdf and a weight per channel");
  if (!ec.has_pdf()) throw std::invalid_argument("--eval-columns: the eval file needs wi, wo, value and pdf");
  DirectionSampleReader d(dump, dc), wi_r(eval, ec.wi_columns(c)), wo_r(eval, ec.wo_columns(c));
  for (DirectionSampleReader* r : {&d, &wi_r, &wo_r}) r->set_frame(o.frame);
  FileRows f;
  std::vector<Vec3<double>> wo(kSampleFileBlock), ewi(kSampleFileBlock), ewo(kSampleFileBlock);
  std::vector<double> pdf(kSampleFileBlock), w(kSampleFileBlock * std::size_t(c)), epdf(kSampleFileBlock),
      ev(kSampleFileBlock * std::size_t(c));
  for (std::size_t n; (n = d.read(wo, pdf, w)) > 0;) {
    if (o.run.cancelled()) throw Cancelled("the file check");
    if (wi_r.read(std::span(ewi.data(), n), std::span(epdf.data(), n), std::span(ev.data(), n * std::size_t(c))) != n ||
        wo_r.read(std::span(ewo.data(), n)) != n)
      throw SampleFileError(fmt::format("{}: fewer rows than the dump {}", eval.string(), dump.string()));
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t row = f.s.wo.size();
      if ((ewi[i] - view).norm() > 1e-4 || (ewo[i] - wo[i]).norm() > 1e-4)
        throw SampleFileError(fmt::format("{}: row {} (0-based) is not the view and the dump's direction", eval.string(), row));
      f.s.wo.push_back(wo[i]);
      f.s.pdf.push_back(pdf[i]);
      f.eval_pdf.push_back(epdf[i]);
      for (int k = 0; k < c; ++k) f.s.weight.push_back(w[i * std::size_t(c) + std::size_t(k)]),
                                  f.eval_value.push_back(ev[i * std::size_t(c) + std::size_t(k)]);
    }
  }
  if (wi_r.read(std::span(ewi.data(), 1), std::span(epdf.data(), 1), std::span(ev.data(), std::size_t(c))) != 0)
    throw SampleFileError(fmt::format("{}: more rows than the dump {}", eval.string(), dump.string()));
  f.s.lost = o.lost;
  f.s.drawn = f.s.wo.size() + o.lost;
  return f;
}

BatteryLine file_consistency(const FileRows& f, int c) {
  std::uint64_t bad = 0;
  std::string first;
  for (std::size_t i = 0; i < f.s.wo.size(); ++i) {
    bool ok = std::abs(f.s.pdf[i] - f.eval_pdf[i]) <= kFileConsistency * std::abs(f.s.pdf[i]) + 1e-300;
    for (std::size_t k = 0; k < std::size_t(c); ++k) {
      const double w = f.s.weight[i * std::size_t(c) + k], e = f.eval_value[i * std::size_t(c) + k] / f.eval_pdf[i];
      ok = ok && std::abs(w - e) <= kFileConsistency * std::abs(w) + 1e-300;
    }
    if (!ok && bad++ == 0)
      first = fmt::format("e.g. row {}: weight {:.6g}, eval / pdf {:.6g}, pdf {:.6g} vs the eval file's {:.6g}", i,
                          f.s.weight[i * std::size_t(c)], f.eval_value[i * std::size_t(c)] / f.eval_pdf[i], f.s.pdf[i],
                          f.eval_pdf[i]);
  }
  return {"consistency", "files",
          bad == 0 ? "weights = eval / pdf and pdfs = the eval file's at every row"
                   : fmt::format("{} of {} rows disagree; {}", bad, f.s.wo.size(), first),
          -1, bad == 0};
}

BatteryLine file_furnace(const FileRows& f, int c, const BsdfFileCheckOptions& o, double level) {
  double s1 = 0, s2 = 0;
  for (std::size_t i = 0; i < f.s.wo.size(); ++i) {
    double x = 0;
    for (int k = 0; k < c; ++k) x += f.s.weight[i * std::size_t(c) + std::size_t(k)] / c;
    s1 += x, s2 += x * x;
  }
  const double n = double(f.s.drawn), mean = s1 / n, se = std::sqrt(std::max(0.0, s2 / n - mean * mean) / (n - 1));
  if (!o.albedo) return {"furnace", "files", fmt::format("mean weight {:.5f} +- {:.5f} (no albedo claimed)", mean, se), -1, true};
  const double p = difference_p({mean, se}, {*o.albedo, 0});
  return {"furnace", "files", fmt::format("mean weight {:.5f} +- {:.5f} against the claimed albedo {:.5f}", mean, se, *o.albedo),
          p, p >= level};
}

}  // namespace

BatteryReport check_bsdf_files(const std::filesystem::path& dump, const SampleColumns& dump_columns,
                               const std::filesystem::path& eval, const EvalColumns& eval_columns,
                               const Vec3<double>& wi, const BsdfFileCheckOptions& options) {
  const FileRows f = read_rows(dump, dump_columns, eval, eval_columns, wi, options);
  if (f.s.wo.empty()) throw SampleFileError(dump.string() + ": no rows");
  const int c = dump_columns.channels();
  BatteryReport r;
  r.lines.push_back(file_consistency(f, c));
  r.lines.push_back(file_furnace(f, c, options, options.level));
  r.passed = true;
  for (const BatteryLine& l : r.lines) r.passed = r.passed && l.passed;
  return r;
}

}  // namespace microsim
