#include "scatter/albedo_table_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <stdexcept>

namespace microsim {

namespace {

std::string number(double x) { return fmt::format("{:.17g}", x); }

std::string joined(const std::vector<double>& values) {
  std::string s;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) s += ',';
    s += number(values[i]);
  }
  return s;
}

const char* side_of(const AlbedoTableRequest& r) { return r.inside ? "inside" : "outside"; }

// The parameters that apply to the table's model, as text.
std::map<std::string, std::string> model_parameters(const AlbedoTableRequest& r) {
  if (r.model == AlbedoModel::analytic) return {{"tolerance", number(r.tolerance)}};
  std::map<std::string, std::string> p{
      {"paths", std::to_string(r.paths)}, {"seed", std::to_string(r.seed)}, {"max_order", std::to_string(r.max_order)}};
  if (r.model == AlbedoModel::surface) p["resolution"] = std::to_string(r.resolution);
  if (r.model == AlbedoModel::smith_walk) p["walk_kernel"] = to_string(r.walk_kernel);
  return p;
}

constexpr const char* kMuRule = "Gauss-Legendre on [0, 1]: E_avg = 2 sum_j mu_weight_j mu_j E_j";

std::string quantity_names(const AlbedoTable& t) {
  std::string s;
  for (const AlbedoQuantity& q : t.quantities) {
    if (!s.empty()) s += ',';
    s += q.name;
  }
  return s;
}

}  // namespace

std::string describe_albedo_request(const AlbedoTableRequest& r) {
  return fmt::format("{} {} {} {}", to_string(r.model), to_string(r.ndf), r.material.describe(), side_of(r));
}

microgeom::ExrImage albedo_table_exr(const AlbedoTable& t) {
  if (t.alphas.empty()) throw std::invalid_argument("albedo table: no complete row to write");
  microgeom::ExrImage image;
  image.width = int(t.mus.size());
  image.height = int(t.alphas.size());
  for (const AlbedoQuantity& q : t.quantities) {
    microgeom::ExrChannel& value = image.add_channel(q.name + ".value");
    microgeom::ExrChannel& error = image.add_channel(q.name + ".error");
    for (std::size_t i = 0; i < q.cells.size(); ++i) {
      value.data[i] = float(q.cells[i].value);
      error.data[i] = float(q.cells[i].standard_error);
    }
    image.attributes[q.name + ".average"] = joined(estimate_values(q.average, false));
    image.attributes[q.name + ".average_error"] = joined(estimate_values(q.average, true));
  }
  const AlbedoTableRequest& r = t.request;
  image.attributes.merge(std::map<std::string, std::string>{
      {"kind", kAlbedoTableKind}, {"model", to_string(r.model)}, {"ndf", to_string(r.ndf)},
      {"material", r.material.describe()}, {"side", side_of(r)}, {"alphas", joined(t.alphas)},
      {"mus", joined(t.mus)}, {"mu_weights", joined(t.mu_weights)}, {"mu_rule", kMuRule}, {"error", t.error_kind()},
      {"quantities", quantity_names(t)}, {"partial", t.partial ? "true" : "false"},
      {"alphas_requested", joined(r.alphas)}});
  image.attributes.merge(model_parameters(r));
  if (t.fresnel_average) image.attributes["F_avg"] = number(*t.fresnel_average);
  return image;
}

namespace {

std::string csv_header(const AlbedoTable& t) {
  std::string h = "alpha,mu,mu_weight";
  for (const AlbedoQuantity& q : t.quantities) h += fmt::format(",{0},{0}_error", q.name);
  for (const AlbedoQuantity& q : t.quantities) h += fmt::format(",{0}_avg,{0}_avg_error", q.name);
  return h + "\n";
}

std::string csv_comments(const AlbedoTable& t) {
  std::string c = fmt::format("# microsim albedo table: {}\n", describe_albedo_request(t.request));
  for (const auto& [key, value] : model_parameters(t.request)) c += fmt::format("# {} {}\n", key, value);
  c += fmt::format("# columns: Q = E(mu, alpha), Q_error = its {}; Q_avg = E_avg(alpha) = 2 int_0^1 E mu dmu\n",
                   t.error_kind());
  c += fmt::format("# mu: {}\n", kMuRule);
  if (t.fresnel_average)
    c += fmt::format("# F_avg {} (the conductor's hemispherical Fresnel average, 2 int_0^1 F mu dmu)\n",
                     number(*t.fresnel_average));
  if (t.partial)
    c += fmt::format("# PARTIAL: {} of {} alphas (interrupted)\n", t.alphas.size(), t.request.alphas.size());
  return c;
}

}  // namespace

std::string albedo_table_csv(const AlbedoTable& t) {
  std::string s = csv_header(t) + csv_comments(t);
  for (std::size_t a = 0; a < t.alphas.size(); ++a)
    for (std::size_t m = 0; m < t.mus.size(); ++m) {
      s += fmt::format("{},{},{}", number(t.alphas[a]), number(t.mus[m]), number(t.mu_weights[m]));
      for (const AlbedoQuantity& q : t.quantities) {
        const Estimate& e = q.cells[a * t.mus.size() + m];
        s += fmt::format(",{},{}", number(e.value), number(e.standard_error));
      }
      for (const AlbedoQuantity& q : t.quantities)
        s += fmt::format(",{},{}", number(q.average[a].value), number(q.average[a].standard_error));
      s += "\n";
    }
  return s;
}

namespace {

nlohmann::json quantity_json(const AlbedoTable& t, const AlbedoQuantity& q) {
  nlohmann::json j = estimate_rows_json(q.cells, t.mus.size());
  j["average"] = estimate_values(q.average, false);
  j["average_error"] = estimate_values(q.average, true);
  return j;
}

}  // namespace

nlohmann::json albedo_table_json(const AlbedoTable& t) {
  const AlbedoTableRequest& r = t.request;
  nlohmann::json j{{"kind", kAlbedoTableKind},
                   {"model", to_string(r.model)},
                   {"ndf", to_string(r.ndf)},
                   {"material", r.material.describe()},
                   {"side", side_of(r)},
                   {"alphas_requested", r.alphas},
                   {"alphas", t.alphas},
                   {"mus", t.mus},
                   {"mu_weights", t.mu_weights},
                   {"mu_rule", kMuRule},
                   {"error", t.error_kind()},
                   {"partial", t.partial},
                   {"seconds", t.seconds},
                   {"row_seconds", t.row_seconds}};
  if (r.model == AlbedoModel::surface) j["build_seconds"] = t.build_seconds;
  if (r.model == AlbedoModel::analytic) j["tolerance"] = r.tolerance;
  else j.update({{"paths", r.paths}, {"seed", r.seed}, {"max_order", r.max_order}});
  if (r.model == AlbedoModel::surface) j["resolution"] = r.resolution;
  if (r.model == AlbedoModel::smith_walk) j["walk_kernel"] = to_string(r.walk_kernel);
  if (t.fresnel_average) j["F_avg"] = *t.fresnel_average;
  j["quantity_names"] = nlohmann::json::array();
  for (const AlbedoQuantity& q : t.quantities) {
    j["quantity_names"].push_back(q.name);
    j["quantities"][q.name] = quantity_json(t, q);
  }
  return j;
}

std::vector<double> estimate_values(const std::vector<Estimate>& estimates, bool errors) {
  std::vector<double> v;
  for (const Estimate& e : estimates) v.push_back(errors ? e.standard_error : e.value);
  return v;
}

nlohmann::json estimate_rows_json(const std::vector<Estimate>& estimates, std::size_t columns) {
  nlohmann::json values = nlohmann::json::array(), errors = nlohmann::json::array();
  for (std::size_t start = 0; columns > 0 && start < estimates.size(); start += columns) {
    const std::vector<Estimate> row(estimates.begin() + std::ptrdiff_t(start),
                                    estimates.begin() + std::ptrdiff_t(std::min(start + columns, estimates.size())));
    values.push_back(estimate_values(row, false));
    errors.push_back(estimate_values(row, true));
  }
  return {{"value", values}, {"error", errors}};
}

}  // namespace microsim
