// microsim check-bsdf-files DUMP EVAL --theta T [--cells CELLS]: one BSDF's consistency with itself from files (a
// sample dump of one view and its eval file at the same rows; measure/bsdf_file_check.h): each weight against
// eval / pdf, each pdf against the eval file's, and the white furnace (the mean weight with its error, against
// --albedo when claimed); with the eval file at the view's cell points (bsdf-queries --cells), the sample
// histogram against the integral of pdf() per cell, the weighted histogram against the integral of eval(), and
// the mean weight against the integral of eval cos.
// Exit 0 every test passed, 1 one rejected, 2 bad usage or input (the files' rows not matching), 130 interrupted.
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "measure/bsdf_file_check.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <memory>
#include <optional>
#include <string>

namespace microsim::app {
namespace {

struct FilesArgs {
  std::string dump, eval, cells, columns = "x,y,z,pdf,weight", eval_columns = "wi,wo,value,pdf", frame = "z-up", json;
  double theta = 0, phi = 0, level = 0.01;
  std::optional<double> albedo;
  unsigned long long lost = 0;
};

int run_check_bsdf_files(const FilesArgs& a) {
  check_distinct_outputs({{"DUMP", a.dump}, {"EVAL", a.eval}, {"--cells", a.cells}}, {{"--json", a.json}});
  check_output("--json", a.json);
  if (a.frame != "z-up" && a.frame != "y-up") throw UsageError(fmt::format("--frame {}: z-up or y-up", quote_excerpt(a.frame)));
  SampleColumns dump_columns;
  EvalColumns eval_columns;
  try {
    dump_columns = SampleColumns::parse(a.columns);
    eval_columns = EvalColumns::parse(a.eval_columns);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--columns / --eval-columns: {}", e.what()));
  }
  BsdfFileCheckOptions o;
  o.frame = a.frame == "y-up" ? SampleFrame::y_up : SampleFrame::z_up;
  o.lost = a.lost, o.level = a.level, o.albedo = a.albedo, o.cells = std::filesystem::path(a.cells);
  install_interrupt_handler();
  o.run = cli_run_control(1, nullptr);
  BatteryReport r;
  try {
    r = check_bsdf_files(std::filesystem::path(a.dump), dump_columns, std::filesystem::path(a.eval), eval_columns,
                         direction_from_degrees(a.theta, a.phi), o);
  } catch (const SampleFileError& e) {
    throw UsageError(e.what());
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-bsdf-files");
  }
  if (!a.json.empty()) {
    nlohmann::json j = to_json(r);
    j.update({{"dump", a.dump}, {"eval", a.eval}, {"theta", a.theta}, {"phi", a.phi}, {"level", a.level}});
    if (!a.cells.empty()) j["cells"] = a.cells;
    write_file_atomically(a.json, j.dump(2) + "\n");
  }
  fmt::print("{:<12} {:>9} {:<9} {}\n", "test", "p", "verdict", "detail");
  for (const BatteryLine& l : r.lines)
    fmt::print("{:<12} {:>9} {:<9} {}\n", l.test, l.p < 0 ? "-" : fmt::format("{:.3g}", l.p), l.verdict_word(), l.detail);
  fmt::print("{}\n", r.passed ? "passed" : "REJECTED");
  return r.passed ? kExitOk : kExitRejected;
}

CommandRegistration check_bsdf_files_registration{"check-bsdf-files", [](CLI::App& app) {
  auto a = std::make_shared<FilesArgs>();
  auto* sub = app.add_subcommand(
      "check-bsdf-files",
      "One BSDF's consistency with itself from files: a sample dump of one view (x, y, z, pdf, weight per channel) and "
      "an eval file of the same BSDF at the same rows (wi = the view, wo = the sample's direction, f |cos wo| per "
      "channel, pdf): each weight against eval / pdf, each pdf against the eval file's (1e-3 relative), and the white "
      "furnace (the mean weight with its standard error, against --albedo when given). With --cells (the same BSDF's "
      "eval file at the view's cell points, `bsdf-queries --cells`): the sample histogram against the integral of its "
      "pdf per cell (density), the weighted histogram against the integral of its eval (integral) and the mean weight "
      "against the integral of eval cos (furnace), Sidak-shared. Exit 0 passed, 1 rejected, 2 bad usage or input.");
  sub->add_option("dump", a->dump, "the sample dump (.npy or text), as validate --from reads it")->required();
  sub->add_option("eval", a->eval, "the eval file at the dump's rows (.npy or text), as check-eval reads it")->required();
  add_number_option(sub, "--theta", a->theta, real({0, 180}), "the view's polar angle in degrees (> 90: from inside)")
      ->required();
  add_number_option(sub, "--phi", a->phi, real(), "the view's azimuth in degrees")->default_str("0");
  sub->add_option("--cells", a->cells,
                  "the eval file (--eval-columns) at the view's cell points, as `bsdf-queries --cells` writes them");
  sub->add_option("--columns", a->columns, "the dump's columns: x, y, z, pdf, weight (one per channel), -")->capture_default_str();
  sub->add_option("--eval-columns", a->eval_columns, "the eval file's columns: wi, wo, value (one per channel), pdf, -")
      ->capture_default_str();
  sub->add_option("--frame", a->frame, "the frame of both files: z-up or y-up")->capture_default_str();
  add_number_option(sub, "--lost", a->lost, whole(), "samples the dump leaves out (lost): they weigh 0 in the furnace")
      ->default_str("0");
  add_number_option(sub, "--albedo", a->albedo, real({0, 10}), "the albedo the BSDF claims at this view (1: energy conserving)");
  add_number_option(sub, "--level", a->level, level(), "family-wise significance level of the statistical tests")->default_str("0.01");
  sub->add_option("--json", a->json, "write the report as JSON");
  on_selected(sub, [a] { return run_check_bsdf_files(*a); });
}};

}  // namespace
}  // namespace microsim::app
