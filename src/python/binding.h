// python: the `microsim` Python module (pybind11), a thin layer over the library: each function parses and
// checks its Python arguments, calls the library function the command line calls, and converts the result
// to numpy arrays and Python objects (docs/guide/python.md). module.cpp (the module, the analytic functions,
// tracing, surfaces, masking, scattering), validate_binding.cpp (the validation, the samplers, the run of long
// calls, the shared converters below) and one file per group of functions registered below.
#pragma once

#include "core/run_control.h"
#include "microfacet/ggx.h"
#include "validate/sample_io.h"

#include <nlohmann/json_fwd.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <functional>
#include <string>

namespace microsim::python {

namespace py = pybind11;

// Registers validate(), ValidationResult, sample() and sampler_names() (validate_binding.cpp).
void bind_validation(py::module_& m);
// Registers albedo_table() and stability() (tables_binding.cpp).
void bind_tables(py::module_& m);
// Registers check_bsdf() (battery_binding.cpp).
void bind_battery(py::module_& m);
// Registers compare_scattering() (compare_binding.cpp).
void bind_compare(py::module_& m);
// Registers merge() (merge_binding.cpp).
void bind_merge(py::module_& m);

// Runs `work(run)` with the GIL released, on a worker thread, while the calling thread waits and, every
// 50 ms and at the end, takes the GIL to pass the latest progress to `progress` (a Python callable
// progress(stage, done, total), or None) and to run Python's signal handlers (PyErr_CheckSignals). A
// KeyboardInterrupt (Ctrl-C) or an exception from the callback cancels the run (RunControl's token) and,
// once the work has returned, is raised with `partial_result()` (called with the GIL held, after the work
// returned; None when empty or when it returns None) as its attribute `partial_result`. An exception of the
// work itself is rethrown as is (translated by the module's exception translator).
void run_interruptible(const std::function<void(const RunControl&)>& work, const py::object& progress,
                       const std::function<py::object()>& partial_result = {});

// The roughness of an `alpha` argument: a number (isotropic) or a pair (alpha_x, alpha_y), checked against
// the supported range as the command line checks --alpha (ValueError naming `what`).
GGX<double> ggx_of(const py::handle& alpha, const char* what = "alpha");

// The view of (theta, phi) in degrees, checked as `validate --theta/--phi` checks them (theta in [0, 90)).
Vec3<double> view_of(double theta_deg, double phi_deg);

// An array of directions (N, 3), float64, C-contiguous (a copy only when the input is not already that):
// for the analytic functions and samplers. ValueError naming `what` for another shape or a non-real dtype.
py::array_t<double, py::array::c_style | py::array::forcecast> directions_of(const py::handle& array, const char* what);

// The array of argument `what`, with a real dtype (float32/float64 when `exact_float`, which also demands a
// numpy array: read in place, never converted), and `columns` columns (0: 1-D; -1: 1-D or any columns); ValueError
// naming `what` otherwise (validate_binding.cpp).
py::array checked_array(const py::handle& object, const char* what, int columns, bool exact_float);
// Column `column` of a checked array (1-D: its only one), read in place by a DirectionSampleReader.
SampleArrayColumn column_of(const py::array& a, int column);

// A JSON document as the Python object json.loads gives (dicts, lists, numbers, strings): what the command
// line's --json writes, returned from Python (validate_binding.cpp).
py::object json_object(const nlohmann::json& j);

}  // namespace microsim::python
