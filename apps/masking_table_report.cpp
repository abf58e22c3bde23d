#include "masking_table_report.h"

#include "command.h"
#include "masking_report.h"

#include "core/atomic_file.h"
#include "core/math.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace microsim::app {

namespace {

// One column of the table: a measured quantity of a view with its Monte Carlo standard error (none for the
// VNDF distances, whose noise is the separate noise-floor column).
struct TableColumn {
  std::string header, key;
  int digits = 3;
  bool has_mc_error = true;
  Estimate (*get)(const MaskingTableView&) = nullptr;
};

using View = MaskingTableView;

std::vector<TableColumn> table_columns(double grazing_share) {
  return {
      {"TV to Smith", "tv_smith_analytic", 4, false, [](const View& r) { return Estimate{r.vndf.tv_analytic, 0}; }},
      {"TV to Smith, own NDF", "tv_smith_empirical", 4, false,
       [](const View& r) { return Estimate{r.vndf.tv_empirical, 0}; }},
      {"TV noise", "tv_noise_floor", 4, false, [](const View& r) { return Estimate{r.vndf.tv_noise, 0}; }},
      {"G1 / Smith G1", "g1_ratio_to_smith_analytic", 3, true,
       [](const View& r) {
         const auto& m = r.masking;
         return Estimate{m.g1.value / m.g1_smith_analytic, m.g1.standard_error / m.g1_smith_analytic};
       }},
      {"facing: G1(v\\|m) / G1", "facing_ratio", 3, true, [](const View& r) { return r.masking.by_normal.back().ratio; }},
      {"grazing decile: G1(v\\|m) / G1", "grazing_decile_ratio", 3, true,
       [](const View& r) { return r.masking.by_normal.front().ratio; }},
      {fmt::format("near-grazing {:g}%: G1(v\\|m) / G1", 100 * grazing_share), "near_grazing_ratio", 3, true,
       [](const View& r) { return r.masking.near_grazing.ratio; }},
      {"near-grazing: angle(m, v) from", "near_grazing_angle_min_deg", 1, false,
       [](const View& r) {
         return Estimate{std::acos(std::clamp(r.masking.near_grazing.hi, -1.0, 1.0)) * 180.0 / kPi<double>, 0};
       }},
      {"mirror pair: G2 / HC Smith", "mirror_pair_g2_ratio", 3, true,
       [](const View& r) { return r.masking.pair_cone->ratio_analytic; }},
      {"mirror lobe: G2 / HC Smith", "mirror_lobe_g2_ratio", 3, true,
       [](const View& r) { return r.masking.mirror->ratio_analytic; }},
      {"leak ratio", "leak_ratio", 4, true, [](const View& r) { return r.masking.leak_ratio; }},
  };
}

// A column's estimates over the realisations of a cell, and their summary.
struct ColumnValues {
  std::vector<Estimate> estimates;
  RealisationSummary summary;
};

ColumnValues column_values(const MaskingTableCell& cell, const TableColumn& column) {
  ColumnValues c;
  for (const View* v : cell.views) c.estimates.push_back(column.get(*v));
  c.summary = summarise_realisations(c.estimates);
  return c;
}

// ---- JSON ------------------------------------------------------------------------------------------------------

nlohmann::json parameters_json(const MaskingTableRequest& r) {
  return {{"assemblies", r.assemblies}, {"alphas", r.alphas},   {"thetas", r.thetas},
          {"phi", r.phi_deg},           {"resolution", r.resolution}, {"corr_cells", r.corr_cells},
          {"seeds", r.seeds},           {"samples", r.samples},   {"vndf_rays", r.vndf_rays},
          {"vndf_lobe_rows", kMaskingVndfRows}, {"grazing_share", r.grazing_share},
          {"ndf_match", std::string(microgeom::to_string(r.ndf_match))}};
}

nlohmann::json view_json(const View& view) {
  nlohmann::json jr;
  jr["theta"] = view.theta;
  jr["vndf"] = to_json(view.vndf);
  jr["vndf_rays"] = view.vndf_rays;
  jr["vndf_rays_per_second"] = view.vndf_rays_per_second;
  jr["masking"] = to_json(view.masking);
  jr["partial"] = view.partial;
  return jr;
}

nlohmann::json surface_json(const MaskingTableSurface& s) {
  nlohmann::json js;
  js["assembly"] = s.assembly;
  js["alpha"] = s.alpha;
  js["seed"] = s.seed;
  js["corr_cells"] = s.corr_cells;
  js["build_seconds"] = s.build_seconds;
  js["scene_seconds"] = s.scene_seconds;
  js["analytic_reference"] = s.analytic_reference;
  for (const View& v : s.views) js["views"].push_back(view_json(v));
  return js;
}

nlohmann::json cell_json(const MaskingTableCell& cell, const std::vector<TableColumn>& columns) {
  nlohmann::json jc = {
      {"assembly", cell.assembly}, {"alpha", cell.alpha}, {"theta", cell.theta}, {"realisations", cell.views.size()}};
  for (const auto& col : columns) {
    const RealisationSummary s = column_values(cell, col).summary;
    jc[col.key] = {{"values", s.values}, {"mean", s.mean}, {"sd_across", s.sd}, {"se_across", s.se_across},
                   {"mc_se", s.mc_se}, {"min", s.min}, {"max", s.max}};
  }
  return jc;
}

nlohmann::json table_json(const MaskingTable& t, const std::vector<MaskingTableCell>& cells,
                          const std::vector<TableColumn>& columns) {
  nlohmann::json j;
  j["parameters"] = parameters_json(t.request);
  for (const auto& s : t.surfaces) j["surfaces"].push_back(surface_json(s));
  j["seconds"] = t.seconds;
  j["peak_rss_mib"] = peak_rss_mib();
  j["partial"] = t.partial;
  j["views_requested"] = t.views_requested();
  j["views_complete"] = t.complete_views().size();
  for (const auto& cell : cells) j["cells"].push_back(cell_json(cell, columns));
  return j;
}

// ---- markdown ----------------------------------------------------------------------------------------------------

std::string markdown_preamble(const MaskingTable& t) {
  const MaskingTableRequest& r = t.request;
  const bool several = r.seeds.size() > 1;
  std::string seed_text;
  for (std::size_t k = 0; k < r.seeds.size(); ++k) seed_text += (k ? "," : "") + std::to_string(r.seeds[k]);
  std::string md;
  if (t.partial)
    md += fmt::format("**PARTIAL: interrupted (Ctrl-C) after {} of {} views; the table holds the complete views "
                      "only.**\n\n",
                      t.complete_views().size(), t.views_requested());
  md += fmt::format("Surfaces {}^2, correlation length {} cells (0 = default), seed{} {}, view azimuth {} deg; per view "
                    "{} VNDF rays (lobe bins {} x {}) and {} surface points; near-grazing class: the bottom {:g}% of "
                    "the front-facing projected area. {:.0f} s in all.\n",
                    r.resolution, r.corr_cells, several ? "s" : "", seed_text, r.phi_deg, r.vndf_rays, kMaskingVndfRows,
                    2 * kMaskingVndfRows, r.samples, 100 * r.grazing_share, t.seconds);
  if (several) {
    md += fmt::format("Each cell: the mean over the {} realisations ± its standard error across them (sd / sqrt({})), "
                      "then in brackets the Monte Carlo error of that mean.\n",
                      r.seeds.size(), r.seeds.size());
  }
  return md;
}

std::string markdown_header(const std::vector<TableColumn>& columns) {
  std::string md = "\n| assembly | alpha | theta |";
  for (const auto& c : columns) md += " " + c.header + " |";
  md += "\n|---|---|---|";
  for (std::size_t k = 0; k < columns.size(); ++k) md += "---|";
  return md + "\n";
}

// One realisation: the value (± its Monte Carlo error); several: mean ± se across [Monte Carlo error].
std::string markdown_entry(const ColumnValues& c, const TableColumn& col, bool several) {
  const RealisationSummary& s = c.summary;
  if (!several)
    return col.has_mc_error ? " " + pm(c.estimates.front(), col.digits) + " |"
                            : fmt::format(" {:.{}f} |", c.estimates.front().value, col.digits);
  if (col.has_mc_error)
    return fmt::format(" {:.{}f} ± {:.{}f} [{:.{}f}] |", s.mean, col.digits, s.se_across, col.digits, s.mc_se,
                       col.digits);
  return fmt::format(" {:.{}f} ± {:.{}f} |", s.mean, col.digits, s.se_across, col.digits);
}

std::string table_markdown(const MaskingTable& t, const std::vector<MaskingTableCell>& cells,
                           const std::vector<TableColumn>& columns) {
  const bool several = t.request.seeds.size() > 1;
  std::string md = markdown_preamble(t) + markdown_header(columns);
  for (const auto& cell : cells) {
    md += fmt::format("| {} | {} | {} |", cell.assembly, cell.alpha, cell.theta);
    for (const auto& col : columns) md += markdown_entry(column_values(cell, col), col, several);
    md += "\n";
  }
  return md;
}

}  // namespace

void print_table_view(const MaskingTableView& v) {
  const MaskingResult& m = v.masking;
  fmt::print(stderr,
             "{:<9} alpha {:<4} seed {:<3} theta {:<3}: TV {:.4f} (own NDF {:.4f}, floor {:.4f}) facing {:.3f} "
             "grazing decile {:.3f} near-grazing {:.3f} G2 pair/HC {:.3f} lobe/HC {:.3f} leak {:.4f} ({:.1f} s)\n",
             v.assembly, v.alpha, v.seed, v.theta, v.vndf.tv_analytic, v.vndf.tv_empirical, v.vndf.tv_noise,
             m.by_normal.back().ratio.value, m.by_normal.front().ratio.value, m.near_grazing.ratio.value,
             m.pair_cone->ratio_analytic.value, m.mirror->ratio_analytic.value, m.leak_ratio.value, v.seconds);
}

int report_masking_table(const MaskingTable& table, const MaskingTableOutputs& outputs) {
  const std::vector<TableColumn> columns = table_columns(table.request.grazing_share);
  const std::vector<MaskingTableCell> cells = masking_table_cells(table);
  const std::string md = table_markdown(table, cells, columns);
  if (!outputs.json.empty()) write_file_atomically(outputs.json, table_json(table, cells, columns).dump(2) + "\n");
  if (!outputs.markdown.empty()) write_file_atomically(outputs.markdown, md);
  fmt::print("{}", md);
  fmt::print("peak RSS {:.1f} MiB\n", peak_rss_mib());
  bool failed = false;
  for (const View* v : table.complete_views()) failed = failed || leak_failed(v->masking);
  if (table.partial) return interrupted_partial_written("trace masking --table", {outputs.json, outputs.markdown});
  return failed ? kExitRejected : kExitOk;
}

}  // namespace microsim::app
