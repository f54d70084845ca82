// The extension module rubble._rubble: the C++ side of the Python package `rubble`
// (python/rubble/ is the pure-Python side). Errors of the libraries become Python exceptions
// with the same messages: SceneError (ValueError) with the file, line and key as attributes,
// CheckpointError and NumericalFailure (RuntimeError), FclibFileError (ValueError), PolyhedronError
// and PackingError (ValueError, as when they were std::invalid_argument); any other
// std::invalid_argument is a ValueError, std::runtime_error a RuntimeError (pybind11's rules).
#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "core/polyhedron.hpp"
#include "nlgs_solver/fclib_file.hpp"
#include "preprocessing/packing.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/run.hpp"
#include "simulation/scene_file.hpp"

namespace py = pybind11;
using namespace rubble;

PYBIND11_MODULE(_rubble, m) {
  m.doc() = "rubble: Contact Dynamics (Moreau-Jean + NLGS) for gravitational aggregates; C++ side of the package";

  // Exception types live as long as the module: kept in statics (pybind11's documented pattern).
  static py::exception<SceneError> scene_error(m, "SceneError", PyExc_ValueError);
  static py::exception<CheckpointError> checkpoint_error(m, "CheckpointError", PyExc_RuntimeError);
  static py::exception<NumericalFailure> numerical_failure(m, "NumericalFailure", PyExc_RuntimeError);
  static py::exception<FclibFileError> fclib_error(m, "FclibFileError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const SceneError& e) {
      // The instance carries the parts of the message, as the C++ SceneError does.
      py::object error = py::reinterpret_borrow<py::object>(scene_error.ptr())(e.what());
      error.attr("file") = e.file;
      error.attr("line") = e.line;
      error.attr("key") = e.key;
      error.attr("message") = e.message;
      PyErr_SetObject(scene_error.ptr(), error.ptr());
    } catch (const CheckpointError& e) {
      checkpoint_error(e.what());
    } catch (const NumericalFailure& e) {
      numerical_failure(e.what());
    } catch (const FclibFileError& e) {
      fclib_error(e.what());
    } catch (const PolyhedronError& e) {
      // Input errors (core/input_error.hpp), hence std::runtime_error; they were
      // std::invalid_argument and stay ValueError in Python.
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const PackingError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  rubble::python::bind_scene(m);
  rubble::python::bind_simulation(m);
  rubble::python::bind_tools(m);
}
