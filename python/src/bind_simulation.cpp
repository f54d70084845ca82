// rubble.Simulation: a scene stepped from Python (simulation.hpp). The state arrays are numpy
// views into the C++ State (no copy); the contacts are copied into arrays. Steps run without the
// GIL (other Python threads, a notebook's event loop, go on meanwhile); between two steps the
// loops check for signals, so Ctrl-C stops them with KeyboardInterrupt at a step boundary.
#include <pybind11/functional.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <variant>

#include "bindings.hpp"
#include "simulation.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::python {
namespace {

/// Marks a simulation as stepping for the guard's lifetime (see Simulation::stepping).
class SteppingGuard {
 public:
  explicit SteppingGuard(Simulation& simulation) : simulation_(simulation) {
    if (simulation_.stepping) {
      throw std::runtime_error("this Simulation is being stepped by another thread; step it from one thread at a time");
    }
    simulation_.stepping = true;
  }
  ~SteppingGuard() { simulation_.stepping = false; }
  SteppingGuard(const SteppingGuard&) = delete;
  SteppingGuard& operator=(const SteppingGuard&) = delete;

 private:
  Simulation& simulation_;
};

/// Refuses changes to a simulation while another thread steps it.
void check_not_stepping(const Simulation& simulation) {
  if (simulation.stepping) throw std::runtime_error("this Simulation is being stepped by another thread");
}

/// One step without the GIL, then a check for signals (Ctrl-C) with it.
void step_once(Simulation& simulation) {
  {
    py::gil_scoped_release release;
    simulation.advance();
  }
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

py::dict stage_dict(const std::array<double, stage_count>& seconds) {
  py::dict d;
  for (std::size_t s = 0; s < stage_count; ++s) d[py::str(std::string(stage_name(static_cast<Stage>(s))))] = seconds[s];
  return d;
}

py::dict report_dict(const StepReport& report) {
  py::dict d;
  d["contacts"] = report.contacts;
  d["active_contacts"] = report.solver.active_contacts;
  d["iterations"] = report.solver.iterations;
  d["residual"] = report.solver.residual;
  d["converged"] = report.solver.converged;
  d["newton_iterations"] = report.solver.newton_iterations;
  d["stage_seconds"] = stage_dict(report.stage_seconds);
  return d;
}

/// The contacts as numpy arrays (a copy: a Contact is 300 bytes of which these are a few).
py::dict contacts_dict(const ContactList& contacts) {
  const auto n = static_cast<py::ssize_t>(contacts.size());
  py::array_t<std::uint32_t> body_a(n), body_b(n), feature_a(n), feature_b(n);
  py::array_t<std::uint8_t> status(n);
  py::array_t<double> gap(n), friction(n), restitution(n);
  py::array_t<double> point({n, py::ssize_t{3}}), normal({n, py::ssize_t{3}}), impulse({n, py::ssize_t{3}}),
      impulse_world({n, py::ssize_t{3}}), angular_impulse({n, py::ssize_t{3}});
  py::array_t<double> frame({n, py::ssize_t{3}, py::ssize_t{3}});
  auto fr = frame.mutable_unchecked<3>();
  auto pt = point.mutable_unchecked<2>();
  auto nm = normal.mutable_unchecked<2>();
  auto im = impulse.mutable_unchecked<2>();
  auto iw = impulse_world.mutable_unchecked<2>();
  auto ai = angular_impulse.mutable_unchecked<2>();
  for (py::ssize_t k = 0; k < n; ++k) {
    const Contact& c = contacts[static_cast<std::size_t>(k)];
    body_a.mutable_at(k) = c.id.body_a;
    body_b.mutable_at(k) = c.id.body_b;
    feature_a.mutable_at(k) = c.id.feature_a;
    feature_b.mutable_at(k) = c.id.feature_b;
    status.mutable_at(k) = static_cast<std::uint8_t>(c.status);
    gap.mutable_at(k) = c.gap;
    friction.mutable_at(k) = c.friction_coefficient;
    restitution.mutable_at(k) = c.normal_restitution;
    const Vec3 world = c.frame * c.impulse;
    for (py::ssize_t i = 0; i < 3; ++i) {
      pt(k, i) = c.point[i];
      nm(k, i) = c.frame(i, 0);
      im(k, i) = c.impulse[i];
      iw(k, i) = world[i];
      ai(k, i) = c.angular_impulse[i];
      // Row j of frame[k] is the frame's column j: n, t, s.
      for (py::ssize_t j = 0; j < 3; ++j) fr(k, j, i) = c.frame(i, j);
    }
  }
  py::dict d;
  d["body_a"] = body_a;
  d["body_b"] = body_b;
  d["feature_a"] = feature_a;
  d["feature_b"] = feature_b;
  d["point"] = point;
  d["normal"] = normal;
  d["frame"] = frame;
  d["gap"] = gap;
  d["impulse"] = impulse;
  d["impulse_world"] = impulse_world;
  d["angular_impulse"] = angular_impulse;
  d["status"] = status;
  d["friction"] = friction;
  d["restitution"] = restitution;
  return d;
}

py::dict metrics_dict(const AggregateMetrics& metrics) {
  const std::vector<std::string> names = metrics_column_names();
  const std::vector<double> row = metrics_row(metrics);
  py::dict d;
  for (std::size_t i = 0; i < names.size(); ++i) d[py::str(names[i])] = row[i];
  return d;
}

/// Material id from a name or an id.
int material_id(const Model& model, const py::object& material) {
  if (py::isinstance<py::str>(material)) {
    const auto name = material.cast<std::string>();
    for (std::size_t i = 0; i < model.materials.size(); ++i) {
      if (model.materials[i].name == name) return static_cast<int>(i);
    }
    throw std::invalid_argument("no material named '" + name + "'");
  }
  return material.cast<int>();
}

/// Copies an (N, width) array into N rows of `width` doubles (strided by `stride` doubles).
void copy_into(const py::handle& values, double* data, std::size_t rows, std::size_t width, std::size_t stride,
               const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(values);
  if (!a || a.ndim() != 2 || static_cast<std::size_t>(a.shape(0)) != rows ||
      static_cast<std::size_t>(a.shape(1)) != width) {
    throw std::invalid_argument(fmt::format("{}: expected an array of shape ({}, {})", what, rows, width));
  }
  const double* in = a.data();
  for (std::size_t i = 0; i < rows * width; ++i) {
    if (!std::isfinite(in[i])) throw std::invalid_argument(fmt::format("{}: row {} is not finite", what, i / width));
  }
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t k = 0; k < width; ++k) data[r * stride + k] = in[r * width + k];
  }
}

/// The first coefficient of a list of Eigen vectors or quaternions (nullptr when empty).
double* first(std::vector<Vec3>& values) { return values.empty() ? nullptr : values.front().data(); }
double* first(std::vector<Quat>& values) { return values.empty() ? nullptr : values.front().coeffs().data(); }

}  // namespace

void bind_simulation(py::module_& m) {
  m.def(
      "_stage_names",
      [] {
        std::vector<std::string> names;
        for (std::size_t s = 0; s < stage_count; ++s) names.emplace_back(stage_name(static_cast<Stage>(s)));
        return names;
      },
      "The stages of a step, in execution order (simulation/step.hpp)");
  py::class_<Simulation> cls(m, "Simulation", R"doc(
A scene being stepped: rubble.Simulation(scene).

The arrays positions, orientations, velocities and angular_velocities are numpy views into the
simulation's own state (no copy, writable; they stay valid as long as the Simulation). Orientations
are unit quaternions body frame -> world frame in the order (x, y, z, w): the order Eigen stores
them in and the order scipy.spatial.transform.Rotation.from_quat takes. The run file and the
checkpoints store (w, x, y, z); rubble.quaternion converts.

N calls of step() give the state of `rubble run` after N steps, bit for bit.)doc");

  cls.def(py::init([](const SceneObject& scene) { return Simulation(scene.scene, scene.text, scene.source); }),
          py::arg("scene"), "Starts at the scene's initial state")
      .def_static(
          "from_checkpoint",
          [](const std::filesystem::path& path) {
            if (std::filesystem::is_directory(path)) {
              // A run folder or its checkpoints folder: the newest valid checkpoint.
              const std::filesystem::path folder =
                  std::filesystem::is_directory(checkpoint_folder(path)) ? checkpoint_folder(path) : path;
              return Simulation::from_checkpoint(load_newest_checkpoint(folder).checkpoint);
            }
            return Simulation::from_checkpoint(read_checkpoint(path));
          },
          py::arg("path"),
          "Goes on from a checkpoint file, or the newest valid one of a folder (a run folder of `rubble run` or a "
          "folder given to save_checkpoint). Raises CheckpointError.")
      .def(
          "step",
          [](Simulation& self, std::int64_t n) {
            SteppingGuard guard(self);
            for (std::int64_t i = 0; i < n; ++i) step_once(self);
          },
          py::arg("n") = 1,
          "Takes n steps (GIL released during each; Ctrl-C stops between two). Raises NumericalFailure on a "
          "non-finite state.")
      .def(
          "run",
          [](py::object self_object, py::object until, const std::function<py::object(py::object)>& callback,
             std::int64_t every) {
            Simulation& self = self_object.cast<Simulation&>();
            if (every < 1) throw std::invalid_argument(fmt::format("every: expected >= 1, got {}", every));
            const RunOptions& options = self.scene().run;
            double end_time = options.end_time;
            bool watch_rest = options.until_rest;
            if (py::isinstance<py::str>(until)) {
              if (until.cast<std::string>() != "rest")
                throw std::invalid_argument("until: expected a time (s), 'rest' or None");
              watch_rest = true;
            } else if (!until.is_none()) {
              end_time = until.cast<double>();
              watch_rest = false;
            }
            SteppingGuard guard(self);
            self.set_watch_rest(watch_rest);
            const std::int64_t steps = self.steps_to(end_time);
            const auto start = std::chrono::steady_clock::now();
            std::int64_t done = 0;
            bool stopped_by_callback = false;
            while (done < steps && !(watch_rest && self.at_rest())) {
              step_once(self);
              ++done;
              if (callback && done % every == 0) {
                const py::object answer = callback(self_object);
                if (!answer.is_none() && !answer.cast<bool>()) {
                  stopped_by_callback = true;
                  break;
                }
              }
            }
            self.write_snapshot();  // as run_scene: the last step's snapshot is always in the run file
            py::dict summary;
            summary["steps"] = done;
            summary["step"] = self.state().step;
            summary["time"] = self.state().time;
            summary["reached_rest"] = watch_rest && self.at_rest();
            summary["stopped_by_callback"] = stopped_by_callback;
            summary["wall_seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            return summary;
          },
          py::arg("until") = py::none(), py::arg("callback") = nullptr, py::arg("every") = 1,
          R"doc(Steps to a time (until=T, s), to rest (until='rest', capped by the scene's end_time) or as the
scene says (until=None: what `rubble run` does). callback(sim) is called every `every` steps;
returning False stops the run. Returns {'steps', 'step', 'time', 'reached_rest',
'stopped_by_callback', 'wall_seconds'}. Ctrl-C raises KeyboardInterrupt between two steps.)doc")
      .def_property_readonly(
          "body_count", [](const Simulation& s) { return s.state().body_count(); }, "bodies, walls included")
      .def_property_readonly(
          "grain_count", [](const Simulation& s) { return s.grain_count(); }, "bodies that are grains")
      .def_property_readonly(
          "time", [](const Simulation& s) { return s.state().time; }, "simulated time, s")
      .def_property_readonly(
          "step_count", [](const Simulation& s) { return s.state().step; }, "steps taken since the scene's start")
      .def_property(
          "dt", [](const Simulation& s) { return s.scene().run.step.integrator.time_step; },
          [](Simulation& s, double h) {
            check_not_stepping(s);
            s.set_time_step(h);
          },
          "time step h, s; may be changed between steps")
      .def_property_readonly(
          "theta", [](const Simulation& s) { return s.scene().run.step.integrator.theta; },
          "theta of the Moreau-Jean scheme")
      .def_property(
          "tolerance", [](Simulation& s) { return s.solver().tolerance; },
          [](Simulation& s, double t) {
            check_not_stepping(s);
            if (!(t > 0.0)) throw std::invalid_argument(fmt::format("tolerance: expected a number > 0, got {}", t));
            s.solver().tolerance = t;
          },
          "NLGS tolerance ([solver] tolerance)")
      .def_property(
          "max_iterations", [](Simulation& s) { return s.solver().max_iterations; },
          [](Simulation& s, int n) {
            check_not_stepping(s);
            if (n < 1) throw std::invalid_argument(fmt::format("max_iterations: expected >= 1, got {}", n));
            s.solver().max_iterations = n;
          },
          "NLGS sweeps at most per step ([solver] max_iterations)")
      .def_property(
          "positions",
          [](py::object self) {
            State& st = self.cast<Simulation&>().state();
            return view_rows(first(st.position), st.body_count(), 3, sizeof(Vec3), self);
          },
          [](Simulation& s, const py::handle& v) {
            check_not_stepping(s);
            copy_into(v, first(s.state().position), s.state().body_count(), 3, 3, "positions");
          },
          "centres of mass, m, world frame: (N, 3) view (no copy)")
      .def_property(
          "velocities",
          [](py::object self) {
            State& st = self.cast<Simulation&>().state();
            return view_rows(first(st.velocity), st.body_count(), 3, sizeof(Vec3), self);
          },
          [](Simulation& s, const py::handle& v) {
            check_not_stepping(s);
            copy_into(v, first(s.state().velocity), s.state().body_count(), 3, 3, "velocities");
          },
          "velocities of the centres of mass, m/s, world frame: (N, 3) view (no copy)")
      .def_property(
          "angular_velocities",
          [](py::object self) {
            State& st = self.cast<Simulation&>().state();
            return view_rows(first(st.angular_velocity), st.body_count(), 3, sizeof(Vec3), self);
          },
          [](Simulation& s, const py::handle& v) {
            check_not_stepping(s);
            copy_into(v, first(s.state().angular_velocity), s.state().body_count(), 3, 3, "angular_velocities");
          },
          "angular velocities, rad/s, world frame: (N, 3) view (no copy)")
      .def_property(
          "orientations",
          [](py::object self) {
            State& st = self.cast<Simulation&>().state();
            return view_rows(first(st.orientation), st.body_count(), 4, sizeof(Quat), self);
          },
          [](Simulation& s, const py::handle& v) {
            check_not_stepping(s);
            copy_into(v, first(s.state().orientation), s.state().body_count(), 4, 4, "orientations");
            for (Quat& q : s.state().orientation) q.normalize();
          },
          "unit quaternions body -> world frame, (N, 4) view (no copy) in the order (x, y, z, w) (scipy's); "
          "assigning normalises them")
      .def(
          "contacts", [](const Simulation& s) { return contacts_dict(s.contacts()); },
          R"doc(The contact points of the last step, as arrays (a copy): body_a, body_b, feature_a, feature_b,
point (n, 3) m, normal (n, 3) from a to b, frame (n, 3, 3) whose rows are n, t, s, gap (m, > 0
apart), impulse (n, 3) on b in the frame (r_n, r_t, r_s) N s, impulse_world (n, 3),
angular_impulse (n, 3) on b in the frame (m_n, m_t, m_s) N m s (rolling and twisting resistance; zero
without), status (0 open, 1 sticking, 2 sliding), friction, restitution.)doc")
      .def_property_readonly(
          "last_step", [](const Simulation& s) { return report_dict(s.last_report()); },
          "what the last step did: contacts, iterations, residual, converged, stage_seconds")
      .def_property_readonly(
          "stage_seconds", [](const Simulation& s) { return stage_dict(s.last_report().stage_seconds); },
          "wall time per stage of the last step, s")
      .def_property_readonly(
          "total_stage_seconds", [](const Simulation& s) { return stage_dict(s.total_stage_seconds()); },
          "wall time per stage summed over the steps this object took, s")
      .def(
          "fix",
          [](Simulation& s, std::size_t body) {
            check_not_stepping(s);
            s.set_fixed(body, true);
          },
          py::arg("body"), "Fixes a grain: it stops and no longer moves (infinite mass) until free(body)")
      .def(
          "free",
          [](Simulation& s, std::size_t body) {
            check_not_stepping(s);
            s.set_fixed(body, false);
          },
          py::arg("body"), "Frees a grain fixed by fix(): its mass and inertia are restored")
      .def("is_fixed", &Simulation::is_fixed, py::arg("body"), "True for fixed grains and walls")
      .def(
          "set_contact_law",
          [](Simulation& s, const py::object& a, const py::object& b, std::optional<double> friction,
             std::optional<double> restitution, std::optional<double> cohesion, std::optional<double> work_of_adhesion,
             std::optional<double> rolling_friction, std::optional<double> twisting_friction,
             std::optional<double> tangential_restitution) {
            check_not_stepping(s);
            const Model& model = s.scene().model;
            const int ia = material_id(model, a), ib = material_id(model, b);
            if (ia < 0 || ib < 0 || ia >= model.contact_laws.material_count ||
                ib >= model.contact_laws.material_count) {
              throw std::invalid_argument(
                  fmt::format("materials ({}, {}): expected ids below {}", ia, ib, model.contact_laws.material_count));
            }
            ContactLaw law = model.contact_laws.get(ia, ib);
            if (friction) law.friction_coefficient = *friction;
            if (restitution) law.normal_restitution = *restitution;
            if (cohesion) law.cohesion = *cohesion;
            if (work_of_adhesion) law.work_of_adhesion = *work_of_adhesion;
            if (rolling_friction) law.rolling_friction = *rolling_friction;
            if (twisting_friction) law.twisting_friction = *twisting_friction;
            if (tangential_restitution) law.tangential_restitution = *tangential_restitution;
            s.set_contact_law(ia, ib, law);
          },
          py::arg("material_a"), py::arg("material_b"), py::kw_only(), py::arg("friction") = py::none(),
          py::arg("restitution") = py::none(), py::arg("cohesion") = py::none(),
          py::arg("work_of_adhesion") = py::none(), py::arg("rolling_friction") = py::none(),
          py::arg("twisting_friction") = py::none(), py::arg("tangential_restitution") = py::none(),
          "Changes the contact law of a material pair (names or ids) from the next step on: friction (mu), "
          "restitution (e_n), cohesion (pull-off force, N), work_of_adhesion (J/m^2), rolling_friction (mu_r), "
          "twisting_friction (mu_t), tangential_restitution (e_t); keys left out keep their value")
      .def(
          "contact_law",
          [](const Simulation& s, const py::object& a, const py::object& b) {
            const Model& model = s.scene().model;
            const ContactLaw& law = model.contact_laws.get(material_id(model, a), material_id(model, b));
            py::dict d;
            d["friction"] = law.friction_coefficient;
            d["restitution"] = law.normal_restitution;
            d["cohesion"] = law.cohesion;
            d["work_of_adhesion"] = law.work_of_adhesion;
            d["rolling_friction"] = law.rolling_friction;
            d["twisting_friction"] = law.twisting_friction;
            d["tangential_restitution"] = law.tangential_restitution;
            return d;
          },
          py::arg("material_a"), py::arg("material_b"),
          "The contact law of a material pair: {'friction', 'restitution', 'cohesion' (N), 'work_of_adhesion' (J/m^2), "
          "'rolling_friction', 'twisting_friction', 'tangential_restitution'}")
      .def_property_readonly(
          "materials",
          [](const Simulation& s) {
            py::list names;
            for (const Material& mat : s.scene().model.materials) names.append(mat.name);
            return names;
          },
          "material names, by id")
      .def_property_readonly(
          "masses", [](const Simulation& s) { return py::array_t<double>(py::cast(s.scene().model.mass)); },
          "kg per body (0 for walls); a copy")
      .def_property_readonly(
          "bounding_radii",
          [](const Simulation& s) { return py::array_t<double>(py::cast(s.scene().model.bounding_radius)); },
          "m per body (sphere radius; circumscribed radius of a polyhedron); a copy")
      .def_property_readonly(
          "is_grain",
          [](const Simulation& s) {
            const Model& model = s.scene().model;
            py::array_t<bool> grain(static_cast<py::ssize_t>(model.body_count()));
            for (std::size_t b = 0; b < model.body_count(); ++b)
              grain.mutable_at(static_cast<py::ssize_t>(b)) = model.is_grain(b);
            return grain;
          },
          "True for grains, False for walls, per body")
      .def(
          "metrics",
          [](const Simulation& s, double impulse_threshold) {
            ContactMetricsOptions options;
            options.impulse_threshold = impulse_threshold;
            return metrics_dict(s.metrics(options));
          },
          py::arg("impulse_threshold") = 0.0,
          "The metrics of `rubble post` now (Z, Z without rattlers, nu, D_max, energies, ...): {name: value}; "
          "definitions in docs/postprocessing.md")
      .def(
          "state_hash", [](const Simulation& s) { return state_hash(s.state()); },
          "CRC-64 of the state (time, step, positions, orientations, velocities): the hash `rubble run` prints")
      .def(
          "record",
          [](Simulation& s, const std::filesystem::path& directory, std::optional<double> end_time) {
            check_not_stepping(s);
            s.record(directory, end_time.value_or(s.scene().run.end_time));
          },
          py::arg("directory"), py::arg("end_time") = py::none(),
          "Writes DIR/run.h5 as `rubble run` does from now on (model, scene, one series row per step, snapshots at "
          "the scene's cadence; end_time sets the default cadence of 100 snapshots); close() finishes it")
      .def("close", &Simulation::close_record, "Writes the last snapshot and closes the run file (if recording)")
      .def_property_readonly(
          "record_path",
          [](const Simulation& s) -> py::object {
            const auto path = s.record_path();
            if (path.empty()) return py::none();
            return py::str(path.string());
          },
          "the run file being written, or None")
      .def("__enter__", [](py::object self) { return self; })
      .def("__exit__", [](Simulation& s, py::args) { s.close_record(); })
      .def(
          "save_checkpoint",
          [](Simulation& s, const std::filesystem::path& folder, int keep) {
            check_not_stepping(s);
            return s.save_checkpoint(folder, keep).string();
          },
          py::arg("folder"), py::arg("keep") = 2,
          "Writes a checkpoint (docs/checkpoints.md) into folder; returns its path. Simulation.from_checkpoint goes "
          "on from it bit for bit")
      .def("branch", &Simulation::branch,
           "A copy at the current step (not recording), to step on independently (e.g. with another friction)")
      .def(
          "to_scene",
          [](const Simulation& s) {
            SceneObject out;
            out.scene = s.scene();
            out.scene.state = s.state();
            out.text = scene_to_toml(out.scene);
            out.source = "<rubble.Simulation.to_scene>";
            return out;
          },
          "The current state as a new scene (every grain explicit, velocities included)")
      .def("__repr__", [](const Simulation& s) {
        return fmt::format("<rubble.Simulation '{}': {} bodies, step {}, t = {} s, dt = {} s>", s.scene().name,
                           s.state().body_count(), s.state().step, s.state().time,
                           s.scene().run.step.integrator.time_step);
      });
}

}  // namespace rubble::python
