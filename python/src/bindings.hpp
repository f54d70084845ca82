#pragma once
// Shared pieces of the Python bindings (module _rubble): the scene object as Python sees it,
// numpy helpers and the functions that register each part of the module.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "simulation/scene.hpp"

namespace rubble::python {

namespace py = pybind11;

// The numpy views rely on Eigen's fixed-size types holding their coefficients and nothing else:
// a std::vector<Vec3> is then N x 3 contiguous doubles and a std::vector<Quat> N x 4 (Eigen
// stores a quaternion's coefficients in the order x, y, z, w: Quaternion::coeffs()).
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be 3 packed doubles for the numpy views");
static_assert(sizeof(Quat) == 4 * sizeof(double), "Quat must be 4 packed doubles for the numpy views");

/// A scene as the module hands it out: the parsed Scene and the text it came from (saved in run
/// files and checkpoints; the model is rebuilt from it when a checkpoint is loaded).
struct SceneObject {
  Scene scene;         ///< model, initial state, run options
  std::string text;    ///< the TOML text
  std::string source;  ///< the name it was parsed under (anchors relative paths, names the file in errors)
};

/// An (N, width) float64 array viewing `data` (N rows of `width` doubles, row stride
/// `stride_bytes`), writable, keeping `base` alive: no copy.
py::array view_rows(double* data, std::size_t rows, std::size_t width, std::size_t stride_bytes, py::handle base);

/// An (N, 3) float64 copy of a list of 3-vectors.
py::array_t<double> copy_vec3(const std::vector<Vec3>& values);

/// A list of 3-vectors from an (N, 3) array-like (checked: shape, finiteness).
std::vector<Vec3> to_vec3_list(const py::handle& array, const char* what);

/// Registers the scene functions (load, parse, write, pack, random polyhedra).
void bind_scene(py::module_& m);
/// Registers the Simulation class.
void bind_simulation(py::module_& m);
/// Registers gravity, post-processing (run files, metrics, VTK) and FCLib.
void bind_tools(py::module_& m);

}  // namespace rubble::python
