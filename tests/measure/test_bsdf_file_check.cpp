// check-bsdf --dump D --eval E (measure/bsdf_file_check.h): a BSDF's sample dump and its eval file at the same rows,
// written here from the BSDFs of battery_bsdfs.h (100000 samples, fixed seeds, level 0.01): the correct conductor,
// dielectric and Kulla-Conty mirror pass (the negative controls); a weight that is not eval / pdf, an eval bug and
// a pdf column that is not the sampler's density are rejected by the consistency test, and a Kulla-Conty lobe that
// does not conserve energy by the furnace against the claimed albedo 1. With the eval file at the view's cell
// points (--cells), float32 .npy files all three: the correct dielectric passes the cell tests too, and a sampler
// that draws the GGX conductor of alpha 0.55 while its pdf(), eval() and weights are those of alpha 0.5 (consistent
// with themselves row by row) is rejected by the density test.
#include "battery_bsdfs.h"
#include "measure/bsdf_file_check.h"
#include "measure/bsdf_self_check.h"
#include "scratch_dir.h"

#include "core/random.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <fstream>

namespace microsim::test {
namespace {

constexpr std::uint64_t kRows = 100'000;

// The dump (x y z pdf weight) and the eval file (wi wo value pdf) of n samples from wi; a pdf_scale != 1 writes
// the dump's pdf column scaled on transmitted rows (a sampler that misstates its density there).
// Returns the lost samples (not in the dump).
std::uint64_t write_files(const WorkedBsdf& w, const Vec3<double>& wi, const std::filesystem::path& dump,
                          const std::filesystem::path& eval, double pdf_scale = 1) {
  std::vector<Vec3<double>> in(kRows, wi), wo(kRows);
  std::vector<double> u(3 * kRows), pdf(kRows), weight(kRows);
  std::vector<unsigned char> kept(kRows);
  for (std::uint64_t i = 0; i < kRows; ++i) {
    CounterRng rng(5, i);
    for (int k = 0; k < 3; ++k) u[3 * i + std::size_t(k)] = rng.uniform();
  }
  w.bsdf.sample(in, u, wo, pdf, weight, kept);
  std::vector<Vec3<double>> kin, kwo;
  for (std::size_t i = 0; i < kRows; ++i)
    if (kept[i]) kin.push_back(wi), kwo.push_back(wo[i]);
  std::vector<double> value(kwo.size()), epdf(kwo.size());
  w.bsdf.eval(kin, kwo, value);
  w.bsdf.pdf(kin, kwo, epdf);
  std::ofstream d(dump), e(eval);
  for (std::size_t i = 0, k = 0; i < kRows; ++i) {
    if (!kept[i]) continue;
    const double p = wo[i].z() < 0 ? pdf[i] * pdf_scale : pdf[i];
    d << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", wo[i].x(), wo[i].y(), wo[i].z(), p, weight[i]);
    e << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", wi.x(), wi.y(), wi.z(), wo[i].x(),
                     wo[i].y(), wo[i].z(), value[k], epdf[k] * (wo[i].z() < 0 ? pdf_scale : 1));
    ++k;
  }
  return kRows - kwo.size();
}

std::map<std::string, bool> check(const WorkedBsdf& w, double theta, std::optional<double> albedo = {}, double pdf_scale = 1) {
  const std::filesystem::path dir = scratch_dir("bsdf_file_check", "files");
  const Vec3<double> wi = direction_from_degrees(theta, 0.0);
  BsdfFileCheckOptions o;
  o.lost = write_files(w, wi, dir / "d.txt", dir / "e.txt", pdf_scale);
  o.albedo = albedo;
  const BatteryReport r = check_bsdf_files(dir / "d.txt", SampleColumns::parse("x,y,z,pdf,weight"), dir / "e.txt",
                                           EvalColumns::parse("wi,wo,value,pdf"), wi, o);
  std::map<std::string, bool> passed;
  for (const BatteryLine& l : r.lines) {
    passed[l.test] = l.passed;
    if (!l.passed) fmt::print("  {} {}: {}\n", w.bsdf.name, l.test, l.detail);
  }
  std::filesystem::remove_all(dir);
  return passed;
}

using Verdicts = std::map<std::string, bool>;

TEST(BsdfFileCheck, CorrectBsdfsPass) {
  EXPECT_EQ(check(exact_conductor(0.3), 30), (Verdicts{{"consistency", true}, {"furnace", true}}));
  EXPECT_EQ(check(exact_dielectric(0.3, TransportMode::radiance), 60),
            (Verdicts{{"consistency", true}, {"furnace", true}}));
  EXPECT_EQ(check(kulla_conty_mirror(0.5), 30, 1.0), (Verdicts{{"consistency", true}, {"furnace", true}}));
}

TEST(BsdfFileCheck, EachPlantedBugIsRejectedByItsTest) {
  EXPECT_FALSE(check(exact_conductor(0.3, PlantedBug::weight_not_eval_over_pdf), 30).at("consistency"));
  EXPECT_FALSE(check(exact_dielectric(0.3, TransportMode::radiance, PlantedBug::eta2_in_transmission), 60).at("consistency"));
  const Verdicts pdf_bug = check(exact_dielectric(0.3, TransportMode::radiance), 60, {}, 1.1);
  EXPECT_FALSE(pdf_bug.at("consistency"));
  const Verdicts lobe = check(kulla_conty_mirror(0.5, PlantedBug::non_reciprocal_lobe), 30, 1.0);
  EXPECT_FALSE(lobe.at("furnace"));
  EXPECT_TRUE(lobe.at("consistency"));
}

// float32 .npy files of one view: the dump (x y z pdf weight) of kRows draws of `sampler` with the pdf and weight
// (eval / pdf) of `bsdf` at the drawn directions, the eval file at its rows, and the eval file at the view's cell
// points (64 per cell). Returns the lost samples.
std::uint64_t write_npy_files(const WorkedBsdf& sampler, const WorkedBsdf& bsdf, const Vec3<double>& wi,
                              const std::filesystem::path& dir) {
  std::vector<Vec3<double>> in(kRows, wi), wo(kRows);
  std::vector<double> u(3 * kRows), pdf(kRows), weight(kRows);
  std::vector<unsigned char> kept(kRows);
  for (std::uint64_t i = 0; i < kRows; ++i) {
    CounterRng rng(7, i);
    for (int k = 0; k < 3; ++k) u[3 * i + std::size_t(k)] = rng.uniform();
  }
  sampler.bsdf.sample(in, u, wo, pdf, weight, kept);
  std::vector<Vec3<double>> kwo;
  for (std::size_t i = 0; i < kRows; ++i)
    if (kept[i]) kwo.push_back(wo[i]);
  const auto table = [&](const std::vector<Vec3<double>>& w, bool dump) {
    const std::vector<Vec3<double>> kin(w.size(), wi);
    std::vector<double> value(w.size()), p(w.size()), t;
    bsdf.bsdf.eval(kin, w, value);
    bsdf.bsdf.pdf(kin, w, p);
    for (std::size_t i = 0; i < w.size(); ++i)
      if (dump) t.insert(t.end(), {w[i].x(), w[i].y(), w[i].z(), p[i], value[i] / p[i]});
      else t.insert(t.end(), {wi.x(), wi.y(), wi.z(), w[i].x(), w[i].y(), w[i].z(), value[i], p[i]});
    return t;
  };
  write_npy_table(dir / "d.npy", table(kwo, true), 5, true);
  write_npy_table(dir / "e.npy", table(kwo, false), 8, true);
  write_npy_table(dir / "c.npy", table(battery::cell_points(64, 3), false), 8, true);
  return kRows - kwo.size();
}

Verdicts check_cells(const WorkedBsdf& sampler, const WorkedBsdf& bsdf, double theta) {
  const std::filesystem::path dir = scratch_dir("bsdf_file_check", "cells");
  const Vec3<double> wi = direction_from_degrees(theta, 0.0);
  BsdfFileCheckOptions o;
  o.lost = write_npy_files(sampler, bsdf, wi, dir);
  o.cells = dir / "c.npy";
  const BatteryReport r = check_bsdf_files(dir / "d.npy", SampleColumns::parse("x,y,z,pdf,weight"), dir / "e.npy",
                                           EvalColumns::parse("wi,wo,value,pdf"), wi, o);
  Verdicts passed;
  for (const BatteryLine& l : r.lines) {
    passed[l.test] = l.passed;
    fmt::print("  {} {}: {}\n", bsdf.bsdf.name, l.test, l.detail);
  }
  std::filesystem::remove_all(dir);
  return passed;
}

TEST(BsdfFileCheck, TheSampleHistogramAgainstThePdfOfTheCellFile) {
  const WorkedBsdf glass = exact_dielectric(0.3, TransportMode::radiance);
  EXPECT_EQ(check_cells(glass, glass, 60),
            (Verdicts{{"consistency", true}, {"density", true}, {"integral", true}, {"furnace", true}}));
  const Verdicts drawn_rougher = check_cells(exact_conductor(0.55), exact_conductor(0.5), 30);
  EXPECT_TRUE(drawn_rougher.at("consistency"));
  EXPECT_FALSE(drawn_rougher.at("density"));
}

// The cells file must be the view's cell points in order: the same points reversed, or a file whose row count is
// not a whole number of cells, are refused.
TEST(BsdfFileCheck, ACellsFileThatIsNotTheCellPointsIsRefused) {
  const std::filesystem::path dir = scratch_dir("bsdf_file_check", "bad_cells");
  const WorkedBsdf glass = exact_dielectric(0.3, TransportMode::radiance);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  BsdfFileCheckOptions o;
  o.lost = write_npy_files(glass, glass, wi, dir);
  o.cells = dir / "c.npy";
  const auto run = [&] {
    check_bsdf_files(dir / "d.npy", SampleColumns::parse("x,y,z,pdf,weight"), dir / "e.npy",
                     EvalColumns::parse("wi,wo,value,pdf"), wi, o);
  };
  std::vector<double> t;
  for (auto w = battery::cell_points(4, 1); const Vec3<double>& p : std::vector(w.rbegin(), w.rend()))
    t.insert(t.end(), {wi.x(), wi.y(), wi.z(), p.x(), p.y(), p.z(), 1.0, 1.0});
  write_npy_table(o.cells.path, t, 8, true);
  EXPECT_THROW(run(), SampleFileError);
  t.resize(t.size() - 8 * 2);
  write_npy_table(o.cells.path, t, 8, true);
  EXPECT_THROW(run(), SampleFileError);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace microsim::test
