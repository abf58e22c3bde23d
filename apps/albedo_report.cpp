#include "albedo_report.h"

#include "command.h"

#include "core/atomic_file.h"
#include "scatter/albedo_table_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cstdio>

#include <unistd.h>

namespace microsim::app {

namespace {

std::string albedo_estimate_text(const Estimate& e) { return fmt::format("{:.6f} +- {:.2g}", e.value, e.standard_error); }

// E_avg per alpha, one column per quantity.
void print_averages(const AlbedoTable& t) {
  fmt::print("{:<8}", "alpha");
  for (const AlbedoQuantity& q : t.quantities) fmt::print(" {:>22}", q.name + "_avg");
  fmt::print("\n");
  for (std::size_t a = 0; a < t.alphas.size(); ++a) {
    fmt::print("{:<8g}", t.alphas[a]);
    for (const AlbedoQuantity& q : t.quantities) fmt::print(" {:>22}", albedo_estimate_text(q.average[a]));
    fmt::print("\n");
  }
}

// E(mu, alpha) of the table's first quantity (E, or E1 for the analytic model).
void print_cells(const AlbedoTable& t) {
  const AlbedoQuantity& q = t.quantities.front();
  fmt::print("\n{}(mu) {:<2}", q.name, "");
  for (const double mu : t.mus) fmt::print(" {:>7.4f}", mu);
  fmt::print("\n");
  for (std::size_t a = 0; a < t.alphas.size(); ++a) {
    fmt::print("{:<8g}", t.alphas[a]);
    for (std::size_t m = 0; m < t.mus.size(); ++m) fmt::print(" {:>7.4f}", q.cells[a * t.mus.size() + m].value);
    fmt::print("\n");
  }
}

}  // namespace

void print_albedo_row(const AlbedoTable& t, std::size_t row) {
  const AlbedoQuantity& q = t.quantities.front();
  const char* clear = ::isatty(STDERR_FILENO) ? "\r\033[K" : "";  // over the progress bar's line
  fmt::print(stderr, "{}albedo: alpha {} done ({} of {}, {:.1f} s): {}_avg = {}\n", clear, t.alphas[row], row + 1,
             t.request.alphas.size(), t.row_seconds[row], q.name, albedo_estimate_text(q.average[row]));
  std::fflush(stderr);
}

int report_albedo_table(const AlbedoTable& t, const AlbedoOutputs& o) {
  if (t.alphas.empty()) return interrupted_nothing_written("albedo", "before the first alpha was complete");
  microgeom::write_exr(o.exr, albedo_table_exr(t));
  if (!o.csv.empty()) write_file_atomically(o.csv, albedo_table_csv(t));
  if (!o.json.empty()) write_file_atomically(o.json, albedo_table_json(t).dump(2) + "\n");
  fmt::print("albedo: {}, {} alphas x {} mus (Gauss-Legendre), errors: {}, {:.1f} s\n",
             describe_albedo_request(t.request), t.alphas.size(), t.mus.size(), t.error_kind(), t.seconds);
  if (t.fresnel_average) fmt::print("F_avg = {:.9f} (the conductor's hemispherical Fresnel average)\n", *t.fresnel_average);
  print_averages(t);
  print_cells(t);
  if (!t.partial) return kExitOk;
  fmt::print("PARTIAL: interrupted after {} of {} alphas; the files hold the complete ones\n", t.alphas.size(),
             t.request.alphas.size());
  fmt::print(stderr, "albedo: interrupted: {} of {} alphas written, marked partial\n", t.alphas.size(),
             t.request.alphas.size());
  return kExitInterrupted;
}

}  // namespace microsim::app
