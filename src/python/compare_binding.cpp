// python: compare_scattering(), what `microsim compare-scattering` runs, returned as the dict its --json
// writes (measure/compare_scattering.h).
#include "python/binding.h"

#include "measure/compare_scattering.h"

#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace microsim::python {

namespace {

// Two or three files of `microsim scatter` or of `microsim trace vndf` compared with one verdict: the dict
// of `compare-scattering --json`, with "passed" beside its "rejected" (one verdict, the command line's).
py::object compare_scattering_of(const std::vector<std::string>& files, bool analytic,
                                 const std::optional<std::string>& orders, double level, int threads,
                                 const py::object& progress) {
  if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores), got " + std::to_string(threads));
  const CompareScatteringRequest request{files, analytic, orders.value_or(""), level};
  std::optional<CompareScatteringResult> result;
  run_interruptible([&](const RunControl& run) {
    RunControl r = run;
    r.threads = threads;
    result = compare_scattering_files(request, r);  // std::invalid_argument: ValueError
  }, progress);
  nlohmann::json j = to_json(*result);
  j["passed"] = !result->rejected();
  return json_object(j);
}

}  // namespace

void bind_compare(py::module_& m) {
  using namespace pybind11::literals;
  m.def("compare_scattering", &compare_scattering_of, "files"_a, py::kw_only(), "analytic"_a = false,
        "orders"_a = py::none(), "level"_a = 0.01, "threads"_a = 0, "progress"_a = py::none(),
        R"(Compares two or three scattering results (`microsim compare-scattering`), with the command line's verdict.

files: paths of `microsim scatter` EXR files (order by order: albedo difference, TV of the shapes with its
noise floor, weighted chi-square homogeneity test; analytic=True adds the exact single scattering of the
first file's configuration) or of `microsim trace vndf` histograms (binning by binning); orders: scatter
files only, a list such as '1,2,total' (default 1,2,3,4,5+,total); level: the family-wise level (Sidak).
Returns the dict `compare-scattering --json` writes, with 'rejected' and 'passed'. Too little data or a bad
file raises ValueError, never a pass.)");
}

}  // namespace microsim::python
