// One BSDF's consistency with itself from a sample dump and an eval file (bsdf_file_check.h).
#include "measure/bsdf_file_check.h"

#include "measure/bsdf_self_check.h"
#include "stats/chi2.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <cmath>
#include <numbers>

namespace microsim {
namespace {

// A direction as the messages print it.
std::string text_of(const Vec3<double>& w) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", w.x(), w.y(), w.z()); }

constexpr double kFileConsistency = 1e-3;  // relative, as the battery's

struct FileRows {
  battery::ViewSamples s;
  std::vector<double> eval_value, eval_pdf;  // per row: channels values, one pdf
};

FileRows read_rows(const BsdfRows& dump, const SampleColumns& dc, const BsdfRows& eval, const EvalColumns& ec,
                   const Vec3<double>& view, const BsdfFileCheckOptions& o) {
  const int c = dc.channels();
  if (const std::string p = dump_columns_problem(dc); !p.empty()) throw std::invalid_argument("--columns: " + p);
  if (const std::string p = eval_columns_problem(ec); !p.empty()) throw std::invalid_argument("--eval-columns: " + p);
  DirectionSampleReader d = dump.open(dc), wi_r = eval.open(ec.wi_columns(c)), wo_r = eval.open(ec.wo_columns(c));
  for (DirectionSampleReader* r : {&d, &wi_r, &wo_r}) r->set_frame(o.frame);
  FileRows f;
  std::vector<Vec3<double>> wo(kSampleFileBlock), ewi(kSampleFileBlock), ewo(kSampleFileBlock);
  std::vector<double> pdf(kSampleFileBlock), w(kSampleFileBlock * std::size_t(c)), epdf(kSampleFileBlock),
      ev(kSampleFileBlock * std::size_t(c));
  for (std::size_t n; (n = d.read(wo, pdf, w)) > 0;) {
    if (o.run.cancelled()) throw Cancelled("the file check");
    if (wi_r.read(std::span(ewi.data(), n), std::span(epdf.data(), n), std::span(ev.data(), n * std::size_t(c))) != n ||
        wo_r.read(std::span(ewo.data(), n)) != n)
      throw SampleFileError(fmt::format("{}: fewer rows than the dump {}", eval.name(), dump.name()));
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t row = f.s.wo.size();
      if ((ewi[i] - view).norm() > 1e-4)
        throw SampleFileError(fmt::format("{}: row {} (0-based): wi {} is not the view {} (--theta, --phi)", eval.name(),
                                          row, text_of(ewi[i]), text_of(view)));
      if ((ewo[i] - wo[i]).norm() > 1e-4)
        throw SampleFileError(fmt::format("{}: row {} (0-based): wo {} is not the dump's direction {} (the files' rows "
                                          "must match one to one)", eval.name(), row, text_of(ewo[i]), text_of(wo[i])));
      f.s.wo.push_back(wo[i]);
      f.s.pdf.push_back(pdf[i]);
      f.eval_pdf.push_back(epdf[i]);
      for (int k = 0; k < c; ++k) f.s.weight.push_back(w[i * std::size_t(c) + std::size_t(k)]),
                                  f.eval_value.push_back(ev[i * std::size_t(c) + std::size_t(k)]);
    }
  }
  if (wi_r.read(std::span(ewi.data(), 1), std::span(epdf.data(), 1), std::span(ev.data(), std::size_t(c))) != 0)
    throw SampleFileError(fmt::format("{}: more rows than the dump {}", eval.name(), dump.name()));
  f.s.lost = o.lost;
  f.s.drawn = f.s.wo.size() + o.lost;
  return f;
}

double channel_mean(const double* v, int channels) {
  double s = 0;
  for (int k = 0; k < channels; ++k) s += v[k];
  return s / channels;
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
  BatteryLine line{"furnace", "files", fmt::format("mean weight {:.5f} +- {:.5f} (no albedo claimed)", mean, se), -1, true, false};
  if (o.albedo) {
    const double p = difference_p({mean, se}, {*o.albedo, 0});
    line = {"furnace", "files", fmt::format("mean weight {:.5f} +- {:.5f} against the claimed albedo {:.5f}", mean, se, *o.albedo),
            p, p >= level};
  }
  battery::fail_if_dominated(battery::weight_dominance(f.s, c), line);
  return line;
}

// How far w lies outside cell c of sphere_cell's partition (in z, and in phi times sin theta): 0 inside.
double outside_cell(const Vec3<double>& w, int c) {
  const int iz = c / battery::kCellsPhi, ip = c % battery::kCellsPhi;
  const double z_lo = -1 + 2.0 * iz / battery::kCellsZ, z_hi = -1 + 2.0 * (iz + 1) / battery::kCellsZ;
  const double dz = std::max({0.0, z_lo - w.z(), w.z() - z_hi});
  const double width = 2 * std::numbers::pi / battery::kCellsPhi, middle = (ip + 0.5) * width;
  const double d = std::remainder(std::atan2(w.y(), w.x()) - middle, 2 * std::numbers::pi);
  return std::max(dz, std::max(0.0, std::abs(d) - width / 2) * std::hypot(w.x(), w.y()));
}

// The cells file: per row the channel mean of its values and its pdf (empty without a pdf column), checked to be
// the view's cell points (rows a multiple of kCells, an even count per cell, wi the view, each block's wo in its
// cell within what storage rounding moves a direction).
struct CellFile {
  std::vector<double> value, pdf;
  std::uint64_t non_finite = 0;  // points whose eval() or pdf() is not finite
};
CellFile read_cells(const BsdfRows& rows, const EvalColumns& ec, int c, const Vec3<double>& view,
                    const BsdfFileCheckOptions& o) {
  DirectionSampleReader wi_r = rows.open(ec.wi_columns(c)), wo_r = rows.open(ec.wo_columns(c));
  for (DirectionSampleReader* r : {&wi_r, &wo_r}) r->set_frame(o.frame);
  std::vector<Vec3<double>> wi(kSampleFileBlock), wo(kSampleFileBlock), all_wo;
  std::vector<double> pdf(kSampleFileBlock), v(kSampleFileBlock * std::size_t(c));
  CellFile f;
  for (std::size_t n; (n = wi_r.read(wi, pdf, v)) > 0;) {
    if (o.run.cancelled()) throw Cancelled("the file check");
    wo_r.read(std::span(wo.data(), n));
    for (std::size_t i = 0; i < n; ++i) {
      if (!((wi[i] - view).norm() <= 1e-4))
        throw SampleFileError(fmt::format("{}: row {} (0-based): wi {} is not the view {} (--theta, --phi)", rows.name(),
                                          all_wo.size(), text_of(wi[i]), text_of(view)));
      all_wo.push_back(wo[i]);
      const double x = channel_mean(&v[i * std::size_t(c)], c);
      const bool finite = std::isfinite(x) && (!ec.has_pdf() || std::isfinite(pdf[i]));
      f.non_finite += !finite;  // counted, and 0 in the integrals
      f.value.push_back(finite ? x : 0);
      if (ec.has_pdf()) f.pdf.push_back(finite ? pdf[i] : 0);
    }
  }
  const std::size_t per = all_wo.size() / battery::kCells;
  if (all_wo.size() % battery::kCells != 0 || per < 2 || per % 2 != 0)
    throw SampleFileError(fmt::format("{}: {} rows, not {} cells of an even number of points (bsdf-queries --cells "
                                      "writes them)", rows.name(), all_wo.size(), battery::kCells));
  for (std::size_t i = 0; i < all_wo.size(); ++i)
    if (!(outside_cell(all_wo[i], int(i / per)) <= 1e-4))
      throw SampleFileError(fmt::format("{}: row {} (0-based): wo is not in cell {} (the file is not the view's cell "
                                        "points, in order, as bsdf-queries --cells writes them)", rows.name(), i, i / per));
  return f;
}

}  // namespace

std::string dump_columns_problem(const SampleColumns& columns) {
  return columns.has_pdf() && columns.channels() >= 1 ? "" : "the dump needs x, y, z, pdf and a weight per channel";
}

std::string eval_columns_problem(const EvalColumns& columns) {
  return columns.has_pdf() ? "" : "the eval file needs wi, wo, value and pdf";
}

DirectionSampleReader BsdfRows::open(const SampleColumns& columns) const {
  return array ? DirectionSampleReader(*array, columns) : DirectionSampleReader(path, columns);
}

BatteryReport check_bsdf_files(const BsdfRows& dump, const SampleColumns& dump_columns, const BsdfRows& eval,
                               const EvalColumns& eval_columns, const Vec3<double>& wi, const BsdfFileCheckOptions& options) {
  const FileRows f = read_rows(dump, dump_columns, eval, eval_columns, wi, options);
  if (f.s.wo.empty()) throw SampleFileError(dump.name() + ": no rows");
  const int c = dump_columns.channels();
  const bool cells = !options.cells.empty();
  const int statistical = (options.albedo ? 1 : 0) + (cells ? (eval_columns.has_pdf() ? 3 : 2) : 0);
  const double level = sidak_significance(options.level, std::max(1, statistical));
  BatteryReport r;
  r.lines.push_back(file_consistency(f, c));
  if (cells) {
    const CellFile g = read_cells(options.cells, eval_columns, c, wi, options);
    if (g.non_finite > 0)
      r.lines.push_back({"finite", "files", fmt::format("{} of {} cell points have a non-finite eval or pdf (0 in the "
                                                        "integrals)", g.non_finite, g.value.size()), -1, false});
    for (BatteryLine& l : battery::cell_tests(f.s, c, g.value, g.pdf, "files", level, r.residuals))
      r.lines.push_back(std::move(l));
  }
  if (options.albedo || !cells) r.lines.push_back(file_furnace(f, c, options, level));
  r.passed = true;
  for (const BatteryLine& l : r.lines) r.passed = r.passed && l.passed;
  return r;
}

}  // namespace microsim
