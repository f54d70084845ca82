// Scenes from Python: load or parse a scene file, the built-in default, `rubble pack`, write a
// scene back as TOML, read its bodies (shapes, masses, polyhedra as vertex and face lists) and
// draw random polyhedra.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <fmt/format.h>
#include <fstream>
#include <sstream>

#include "bindings.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "simulation/pack_scene.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::python {

py::array view_rows(double* data, std::size_t rows, std::size_t width, std::size_t stride_bytes, py::handle base) {
  return py::array(py::dtype::of<double>(), {static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(width)},
                   {static_cast<py::ssize_t>(stride_bytes), static_cast<py::ssize_t>(sizeof(double))}, data, base);
}

py::array_t<double> copy_vec3(const std::vector<Vec3>& values) {
  py::array_t<double> out({static_cast<py::ssize_t>(values.size()), static_cast<py::ssize_t>(3)});
  auto w = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < values.size(); ++i) {
    for (py::ssize_t k = 0; k < 3; ++k) w(static_cast<py::ssize_t>(i), k) = values[i][k];
  }
  return out;
}

std::vector<Vec3> to_vec3_list(const py::handle& array, const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!a || a.ndim() != 2 || a.shape(1) != 3)
    throw std::invalid_argument(fmt::format("{}: expected an (N, 3) array", what));
  std::vector<Vec3> values(static_cast<std::size_t>(a.shape(0)));
  const auto r = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    values[static_cast<std::size_t>(i)] = Vec3(r(i, 0), r(i, 1), r(i, 2));
    if (!values[static_cast<std::size_t>(i)].allFinite()) {
      throw std::invalid_argument(fmt::format("{}: row {} is not finite", what, i));
    }
  }
  return values;
}

namespace {

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path.string(), 0, "", "cannot open the scene file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

const char* shape_name(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::sphere:
      return "sphere";
    case ShapeKind::polyhedron:
      return "polyhedron";
    case ShapeKind::plane:
      return "plane";
    case ShapeKind::box:
      return "box";
  }
  return "unknown";
}

/// A polyhedron as Python wants it: vertices (n, 3) and a list of faces (int arrays).
py::dict polyhedron_dict(const ConvexPolyhedron& shape) {
  py::list faces;
  for (const auto face : shape.faces) {
    py::array_t<int> f(static_cast<py::ssize_t>(face.size()));
    std::copy(face.begin(), face.end(), f.mutable_data());
    faces.append(f);
  }
  py::dict d;
  d["vertices"] = copy_vec3(shape.vertices);
  d["faces"] = faces;
  d["volume"] = shape.volume;
  d["principal_inertia_per_density"] =
      py::make_tuple(shape.principal_inertia_per_density.x(), shape.principal_inertia_per_density.y(),
                     shape.principal_inertia_per_density.z());
  d["bounding_radius"] = shape.bounding_radius;
  return d;
}

const char* gravity_name(GravitySettings::Kind kind) {
  switch (kind) {
    case GravitySettings::Kind::none:
      return "none";
    case GravitySettings::Kind::uniform:
      return "uniform";
    case GravitySettings::Kind::self:
      return "self";
    case GravitySettings::Kind::central:
      return "central";
  }
  return "unknown";
}

}  // namespace

void bind_scene(py::module_& m) {
  py::class_<SceneObject>(m, "Scene",
                          "A scene: model (shapes, masses, materials, contact laws), initial state and run options. "
                          "Made by load_scene, parse_scene, default_scene or pack; run it with Simulation(scene).")
      .def_property_readonly(
          "name", [](const SceneObject& s) { return s.scene.name; }, "the scene's name")
      .def_property_readonly(
          "text", [](const SceneObject& s) { return s.text; }, "the TOML text the scene was parsed from")
      .def_property_readonly(
          "source", [](const SceneObject& s) { return s.source; }, "the file name the scene was parsed under")
      .def_property_readonly(
          "body_count", [](const SceneObject& s) { return s.scene.model.body_count(); },
          "bodies, walls included (grains first, then walls)")
      .def_property_readonly(
          "grain_count",
          [](const SceneObject& s) {
            std::size_t n = 0;
            for (std::size_t b = 0; b < s.scene.model.body_count(); ++b) n += s.scene.model.is_grain(b);
            return n;
          },
          "bodies that are grains (spheres or polyhedra)")
      .def_property_readonly(
          "dt", [](const SceneObject& s) { return s.scene.run.step.integrator.time_step; },
          "time step h, s (chosen by the scene's rule when dt = \"auto\")")
      .def_property(
          "end_time", [](const SceneObject& s) { return s.scene.run.end_time; },
          [](SceneObject& s, double t) {
            if (!(t > 0.0)) throw std::invalid_argument(fmt::format("end_time: expected a number > 0, got {}", t));
            s.scene.run.end_time = t;
          },
          "end time of the run, s (the latest end when until = \"rest\"); like rubble run --end-time")
      .def_property_readonly(
          "until_rest", [](const SceneObject& s) { return s.scene.run.until_rest; },
          "the run stops once the grains are at rest")
      .def_property_readonly(
          "seed", [](const SceneObject& s) { return s.scene.run.seed; }, "the scene's seed")
      .def_property(
          "output_directory", [](const SceneObject& s) { return s.scene.run.output.directory; },
          [](SceneObject& s, const std::string& d) { s.scene.run.output.directory = d; },
          "folder of run.h5 and checkpoints; like rubble run --out")
      .def_property_readonly(
          "gravity", [](const SceneObject& s) { return gravity_name(s.scene.run.step.gravity.kind); },
          "none, uniform, self (direct or tree) or central")
      .def_property_readonly(
          "materials",
          [](const SceneObject& s) {
            py::list names;
            for (const Material& mat : s.scene.model.materials) names.append(mat.name);
            return names;
          },
          "material names, by material id")
      .def_property_readonly(
          "shapes",
          [](const SceneObject& s) {
            py::list kinds;
            for (const ShapeKind k : s.scene.model.shape_kind) kinds.append(shape_name(k));
            return kinds;
          },
          "shape of each body: sphere, polyhedron, plane or box")
      .def_property_readonly(
          "masses", [](const SceneObject& s) { return py::array_t<double>(py::cast(s.scene.model.mass)); },
          "kg per body (0 for walls); a copy")
      .def_property_readonly(
          "bounding_radii",
          [](const SceneObject& s) { return py::array_t<double>(py::cast(s.scene.model.bounding_radius)); },
          "m per body: the radius of a sphere, the circumscribed radius of a polyhedron (inf for planes)")
      .def_property_readonly(
          "volumes", [](const SceneObject& s) { return py::array_t<double>(py::cast(s.scene.model.volume)); },
          "m^3 per body (0 for walls)")
      .def_property_readonly(
          "material_ids", [](const SceneObject& s) { return py::array_t<int>(py::cast(s.scene.model.material)); },
          "material id per body")
      .def_property_readonly(
          "positions", [](const SceneObject& s) { return copy_vec3(s.scene.state.position); },
          "initial positions, m, (N, 3); a copy")
      .def_property_readonly(
          "velocities", [](const SceneObject& s) { return copy_vec3(s.scene.state.velocity); },
          "initial velocities, m/s, (N, 3); a copy")
      .def(
          "polyhedron",
          [](const SceneObject& s, std::size_t body) {
            const Model& model = s.scene.model;
            if (body >= model.body_count() || model.shape_kind[body] != ShapeKind::polyhedron) {
              throw std::invalid_argument(fmt::format("body {}: not a polyhedron", body));
            }
            return polyhedron_dict(model.polyhedra[static_cast<std::size_t>(model.shape_index[body])]);
          },
          py::arg("body"),
          "The shape of polyhedral body `body` in its body frame: {'vertices': (n, 3) m, 'faces': [int arrays, "
          "counter-clockwise seen from outside], 'volume', 'principal_inertia_per_density', 'bounding_radius'}")
      .def(
          "to_toml", [](const SceneObject& s) { return scene_to_toml(s.scene); },
          "The scene as TOML with every grain and wall listed (generators expanded); parse_scene reads it back")
      .def(
          "write",
          [](const SceneObject& s, const std::filesystem::path& path, bool explicit_grains) {
            const std::string text = explicit_grains ? scene_to_toml(s.scene) : s.text;
            std::ofstream out(path, std::ios::binary);
            out << text;
            out.close();
            if (!out) throw std::runtime_error(path.string() + ": cannot write the scene file");
          },
          py::arg("path"), py::arg("explicit") = false,
          "Writes the scene file: its own text, or with explicit=True every grain listed (to_toml)")
      .def("__repr__", [](const SceneObject& s) {
        return fmt::format("<rubble.Scene '{}': {} bodies, dt = {} s, end_time = {} s>", s.scene.name,
                           s.scene.model.body_count(), s.scene.run.step.integrator.time_step, s.scene.run.end_time);
      });

  m.def(
      "load_scene",
      [](const std::filesystem::path& path) {
        SceneObject s;
        s.scene = load_scene_file(path);  // its SceneError first (also for a missing file)
        s.text = read_text(path);
        s.source = std::filesystem::absolute(path).string();
        return s;
      },
      py::arg("path"), "Reads a scene file (TOML, docs/scene-file.md). Raises SceneError (file, line, key, message).");
  m.def(
      "parse_scene",
      [](const std::string& text, const std::string& source) {
        SceneObject s;
        s.scene = parse_scene(text, source);
        s.text = text;
        s.source = source;
        return s;
      },
      py::arg("text"), py::arg("source") = "<string>",
      "Parses scene text; `source` names it in error messages and anchors relative paths. Raises SceneError.");
  m.def(
      "default_scene",
      [](const std::string& variant) {
        if (variant != "spheres" && variant != "polyhedra") {
          throw std::invalid_argument("variant: expected 'spheres' or 'polyhedra', got '" + variant + "'");
        }
        const DefaultScene which = variant == "polyhedra" ? DefaultScene::polyhedra : DefaultScene::spheres;
        SceneObject s;
        s.text = default_scene_toml(which);
        s.source = "<built-in default scene>";
        s.scene = parse_scene(s.text, s.source);
        return s;
      },
      py::arg("variant") = "spheres",
      "The built-in scene of `rubble run` without a file: 1000 spheres (or polyhedra) accreting under self-gravity "
      "until at rest");

  m.def(
      "_pack",
      [](const PackOptions& options) {
        SceneObject s;
        s.text = pack_scene_text(options);
        s.source = "<rubble pack " + options.kind + ">";
        s.scene = parse_scene(s.text, s.source);
        if (options.explicit_grains) s.text = scene_to_toml(s.scene);
        return s;
      },
      py::arg("options"));
  py::class_<PackOptions>(m, "_PackOptions")
      .def(py::init<>())
      .def_readwrite("kind", &PackOptions::kind)
      .def_readwrite("count", &PackOptions::count)
      .def_readwrite("shape", &PackOptions::shape)
      .def_readwrite("polyhedron_fraction", &PackOptions::polyhedron_fraction)
      .def_readwrite("d_min", &PackOptions::d_min)
      .def_readwrite("d_max", &PackOptions::d_max)
      .def_readwrite("distribution", &PackOptions::distribution)
      .def_readwrite("bins", &PackOptions::bins)
      .def_readwrite("bin_fractions", &PackOptions::bin_fractions)
      .def_readwrite("density", &PackOptions::density)
      .def_readwrite("friction", &PackOptions::friction)
      .def_readwrite("restitution", &PackOptions::restitution)
      .def_readwrite("seed", &PackOptions::seed)
      .def_readwrite("volume_fraction", &PackOptions::volume_fraction)
      .def_readwrite("cloud_radius", &PackOptions::cloud_radius)
      .def_readwrite("box_width", &PackOptions::box_width)
      .def_readwrite("g", &PackOptions::g)
      .def_readwrite("end_time", &PackOptions::end_time)
      .def_readwrite("name", &PackOptions::name)
      .def_readwrite("explicit_grains", &PackOptions::explicit_grains);
  m.def("_pack_command_line", &pack_command_line, py::arg("options"));

  m.def(
      "random_polyhedron",
      [](std::uint64_t seed, double diameter, int min_vertices, int max_vertices, double min_elongation,
         double min_platyness, double merge_angle_degrees) {
        RandomPolyhedronOptions options;
        options.diameter = diameter;
        options.min_vertices = min_vertices;
        options.max_vertices = max_vertices;
        options.min_elongation = min_elongation;
        options.min_platyness = min_platyness;
        options.merge_angle_degrees = merge_angle_degrees;
        return polyhedron_dict(generate_random_polyhedron(options, seed));
      },
      py::arg("seed"), py::arg("diameter") = 1.0, py::arg("min_vertices") = 10, py::arg("max_vertices") = 70,
      py::arg("min_elongation") = 0.5, py::arg("min_platyness") = 0.5, py::arg("merge_angle_degrees") = 1.0,
      "A random convex polyhedron as in the accretion study (same seed, same shape), in its principal body frame: "
      "{'vertices', 'faces', 'volume', 'principal_inertia_per_density', 'bounding_radius'}");
}

}  // namespace rubble::python
