// The standalone tools from Python: the gravity field of N point masses (gravity/), run files read
// back with their metrics and `rubble post` (postprocessing/), the VTK writer, and FCLib problems
// solved by the simulation's NLGS (nlgs_solver/). The pure-Python modules rubble.gravity,
// rubble.post and rubble.fclib wrap these with numpy/scipy conveniences.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <fmt/format.h>
#include <iostream>
#include <span>

#include "bindings.hpp"
#include "gravity/gravity.hpp"
#include "nlgs_solver/fclib_file.hpp"
#include "nlgs_solver/local_problem.hpp"
#include "postprocessing/metrics.hpp"
#include "postprocessing/post.hpp"
#include "postprocessing/run_reader.hpp"
#include "postprocessing/vtk_output.hpp"
#include "simulation.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::python {
namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// The potential-energy settings and time step of a run, from the scene text stored in its run
/// file (what `rubble post` does; a scene that does not parse leaves no potential and h = 0).
struct RunSettings {
  PotentialSettings potential{};
  double time_step = 0.0;
};

RunSettings settings_from_scene_text(const std::string& text, const std::string& source) {
  RunSettings settings;
  try {
    Scene scene = parse_scene(text, source);
    settings.time_step = scene.run.step.integrator.time_step;
    settings.potential = Simulation(std::move(scene), text, source).potential_settings();
  } catch (const std::exception&) {
    // As `rubble post`: potential energy left at 0, h estimated from the series.
  }
  return settings;
}

py::dict snapshot_dict(const RunSnapshot& snapshot) {
  const State& st = snapshot.state;
  py::dict d;
  d["time"] = st.time;
  d["step"] = st.step;
  d["positions"] = copy_vec3(st.position);
  d["velocities"] = copy_vec3(st.velocity);
  d["angular_velocities"] = copy_vec3(st.angular_velocity);
  py::array_t<double> q({static_cast<py::ssize_t>(st.body_count()), py::ssize_t{4}});
  auto w = q.mutable_unchecked<2>();
  for (std::size_t b = 0; b < st.body_count(); ++b) {
    for (py::ssize_t k = 0; k < 4; ++k) w(static_cast<py::ssize_t>(b), k) = st.orientation[b].coeffs()[k];
  }
  d["orientations"] = q;  // (x, y, z, w), as Simulation.orientations
  const auto n = static_cast<py::ssize_t>(snapshot.contacts.size());
  py::array_t<std::uint32_t> a(n), b(n);
  py::array_t<std::uint8_t> status(n);
  py::array_t<double> gap(n), point({n, py::ssize_t{3}}), normal({n, py::ssize_t{3}}), impulse({n, py::ssize_t{3}}),
      angular_impulse({n, py::ssize_t{3}});
  for (py::ssize_t k = 0; k < n; ++k) {
    const Contact& c = snapshot.contacts[static_cast<std::size_t>(k)];
    a.mutable_at(k) = c.id.body_a;
    b.mutable_at(k) = c.id.body_b;
    status.mutable_at(k) = static_cast<std::uint8_t>(c.status);
    gap.mutable_at(k) = c.gap;
    for (py::ssize_t i = 0; i < 3; ++i) {
      point.mutable_at(k, i) = c.point[i];
      normal.mutable_at(k, i) = c.frame(i, 0);
      impulse.mutable_at(k, i) = c.impulse[i];
      angular_impulse.mutable_at(k, i) = c.angular_impulse[i];
    }
  }
  py::dict contacts;
  contacts["body_a"] = a;
  contacts["body_b"] = b;
  contacts["point"] = point;
  contacts["normal"] = normal;
  contacts["gap"] = gap;
  contacts["impulse"] = impulse;
  contacts["angular_impulse"] = angular_impulse;
  contacts["status"] = status;
  d["contacts"] = contacts;
  return d;
}

LocalProblemOptions fclib_options(double tolerance, int max_iterations, double relaxation, const std::string& order,
                                  std::uint64_t seed, const std::string& polish) {
  LocalProblemOptions options;
  options.tolerance = tolerance;
  options.max_iterations = max_iterations;
  options.relaxation = relaxation;
  options.seed = seed;
  if (order == "as_stored") {
    options.order = SweepOrder::as_stored;
  } else if (order == "shuffled") {
    options.order = SweepOrder::shuffled;
  } else {
    throw std::invalid_argument("order: expected 'as_stored' or 'shuffled', got '" + order + "'");
  }
  if (polish == "none") {
    options.polish = PolishMethod::none;
  } else if (polish == "newton") {
    options.polish = PolishMethod::newton;
  } else {
    throw std::invalid_argument("polish: expected 'none' or 'newton', got '" + polish + "'");
  }
  return options;
}

py::dict solve_problem(const LocalProblem& problem, const LocalProblemOptions& options) {
  LocalProblemSolution solution;
  {
    py::gil_scoped_release release;
    solution = solve_local_problem(problem, options);
  }
  py::dict d;
  d["r"] = py::array_t<double>(py::cast(solution.r));
  d["u"] = py::array_t<double>(py::cast(solution.u));
  d["iterations"] = solution.iterations;
  d["newton_iterations"] = solution.newton_iterations;
  d["error"] = solution.error;
  d["point_residual"] = py::array_t<double>(py::cast(point_residuals(problem, solution.r, solution.u)));
  d["converged"] = solution.converged;
  d["contacts"] = problem.contact_count();
  return d;
}

/// rubble.gravity.field's core (python/rubble/gravity.py): the field of N point masses, the GIL
/// released during the evaluation. Returns (acceleration, potential or None, build s, walk s,
/// transfer s).
py::tuple gravity_field(const DoubleArray& positions, const DoubleArray& masses, const std::string& method,
                        double theta, int order, double G, double softening, bool with_potential, int leaf_size,
                        int group_size, const std::string& precision, const std::string& backend) {
  if (positions.ndim() != 2 || positions.shape(1) != 3)
    throw gravity::GravityError("positions: expected an (N, 3) array");
  if (masses.ndim() != 1 || masses.shape(0) != positions.shape(0)) {
    throw gravity::GravityError(fmt::format("masses: expected {} values (one per position), got shape {}",
                                            positions.shape(0), masses.ndim() == 1 ? masses.shape(0) : -1));
  }
  gravity::GravityOptions options;
  if (method == "direct") {
    options.method = gravity::Method::direct;
  } else if (method == "tree") {
    options.method = gravity::Method::tree;
  } else {
    throw gravity::GravityError("method: expected 'direct' or 'tree', got '" + method + "'");
  }
  options.theta = theta;
  options.order = order;
  options.G = G;
  options.leaf_size = leaf_size;
  options.group_size = group_size;
  if (precision == "single") {
    options.precision = gravity::KernelPrecision::single_precision;
  } else if (precision != "double") {
    throw gravity::GravityError("precision: expected 'double' or 'single', got '" + precision + "'");
  }
  if (backend == "cuda") {
    options.backend = gravity::Backend::cuda;
  } else if (backend != "cpu") {
    throw gravity::GravityError("backend: expected 'cpu' or 'cuda', got '" + backend + "'");
  }
  if (softening > 0.0) options.softening = {gravity::Softening::Kind::plummer, softening};
  if (softening < 0.0) throw gravity::GravityError(fmt::format("softening: expected >= 0, got {}", softening));
  const auto n = static_cast<std::size_t>(positions.shape(0));
  py::array_t<double> acceleration({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  py::array_t<double> potential(with_potential ? static_cast<py::ssize_t>(n) : 0);
  const std::span<const double> x(positions.data(), 3 * n), mass(masses.data(), n);
  const std::span<double> a(acceleration.mutable_data(), 3 * n);
  const std::span<double> phi(potential.mutable_data(), with_potential ? n : 0);
  gravity::FieldTimings timings;
  {
    py::gil_scoped_release release;
    // compute_field checks the input and the backend itself (GravityError, BackendUnavailable
    // with the reason); the exception reaches Python once the GIL is taken back.
    timings = gravity::compute_field(options, x, mass, a, phi);
  }
  return py::make_tuple(acceleration, with_potential ? py::object(potential) : py::object(py::none()),
                        timings.build_seconds, timings.walk_seconds, timings.transfer_seconds);
}

}  // namespace

void bind_tools(py::module_& m) {
  // ---- gravity ----
  m.def("_gravity_field", gravity_field, py::arg("positions"), py::arg("masses"), py::arg("method"), py::arg("theta"),
        py::arg("order"), py::arg("G"), py::arg("softening"), py::arg("potential"), py::arg("leaf_size"),
        py::arg("group_size"), py::arg("precision"), py::arg("backend"));

  // ---- run files ----
  py::class_<RunReader>(m, "RunReader", "A run file (run.h5) open for reading: model, scene text, series, snapshots")
      .def(py::init([](const std::filesystem::path& path) { return RunReader::open(path); }), py::arg("path"))
      .def_property_readonly(
          "path", [](const RunReader& r) { return r.path().string(); }, "the file")
      .def_property_readonly("scene_text", &RunReader::scene_text, "the scene as TOML")
      .def_property_readonly("snapshot_count", &RunReader::snapshot_count, "snapshots in the file")
      .def_property_readonly(
          "body_count", [](const RunReader& r) { return r.model().body_count(); }, "bodies")
      .def_property_readonly("time_step", &RunReader::time_step, "h, s, estimated from the series")
      .def(
          "snapshot",
          [](const RunReader& r, std::int64_t index) {
            const auto count = static_cast<std::int64_t>(r.snapshot_count());
            if (index < 0) index += count;
            if (index < 0 || index >= count)
              throw py::index_error(fmt::format("snapshot {}: the file has {}", index, count));
            return snapshot_dict(r.read_snapshot(static_cast<std::size_t>(index)));
          },
          py::arg("index"),
          "Snapshot `index` (negative counts from the end): time, step, positions, orientations (x, y, z, w), "
          "velocities, angular_velocities, contacts")
      .def(
          "series",
          [](const RunReader& r) {
            const RunSeries s = r.read_series();
            py::dict d;
            d["step"] = py::array_t<std::int64_t>(py::cast(s.step));
            d["time"] = py::array_t<double>(py::cast(s.time));
            d["kinetic_energy"] = py::array_t<double>(py::cast(s.kinetic_energy));
            d["contacts"] = py::array_t<std::int64_t>(py::cast(s.contacts));
            d["active_contacts"] = py::array_t<std::int64_t>(py::cast(s.active_contacts));
            d["iterations"] = py::array_t<std::int64_t>(py::cast(s.iterations));
            d["residual"] = py::array_t<double>(py::cast(s.residual));
            d["wall_seconds"] = py::array_t<double>(py::cast(s.wall_seconds));
            py::dict stages;
            for (std::size_t i = 0; i < s.stage_names.size(); ++i) {
              stages[py::str(s.stage_names[i])] = py::array_t<double>(py::cast(s.stage_seconds[i]));
            }
            d["stage_seconds"] = stages;
            return d;
          },
          "The per-step series: {column: array}")
      .def(
          "metrics",
          [](const RunReader& r, int every, double impulse_threshold) {
            if (every < 1) throw std::invalid_argument(fmt::format("every: expected >= 1, got {}", every));
            const RunSettings settings = settings_from_scene_text(r.scene_text(), r.path().string() + ":/scene");
            ContactMetricsOptions options;
            options.impulse_threshold = impulse_threshold;
            const std::vector<std::string> names = metrics_column_names();
            std::vector<std::vector<double>> columns(names.size());
            const std::size_t count = r.snapshot_count();
            const GrainSizes sizes = grain_sizes(r.model());  // once: one enclosing ball per polyhedron
            for (std::size_t i = 0; i < count; ++i) {
              if (i % static_cast<std::size_t>(every) != 0 && i + 1 != count) continue;  // the last one always
              const RunSnapshot snapshot = r.read_snapshot(i);
              const std::vector<double> row = metrics_row(
                  compute_metrics(r.model(), sizes, snapshot.state, snapshot.contacts, settings.potential, options));
              for (std::size_t c = 0; c < names.size(); ++c) columns[c].push_back(row[c]);
            }
            py::dict d;
            for (std::size_t c = 0; c < names.size(); ++c)
              d[py::str(names[c])] = py::array_t<double>(py::cast(columns[c]));
            return d;
          },
          py::arg("every") = 1, py::arg("impulse_threshold") = 0.0,
          "The metrics of `rubble post` for every `every`-th snapshot (and the last): {name: array}");

  m.def(
      "_post_process_run",
      [](const std::filesystem::path& run_file, const std::filesystem::path& output, bool vtk, bool plots, int every,
         int bins, const std::string& python, const std::filesystem::path& plots_script) {
        PostOptions options;
        options.output_directory = output;
        options.write_vtk = vtk;
        options.plots = plots;
        options.plot.python = python;
        options.plot.script = plots_script;
        options.warnings = &std::cerr;
        options.every = every;
        options.histogram_bins = bins;
        {
          const RunReader reader = RunReader::open(run_file);
          const RunSettings settings = settings_from_scene_text(reader.scene_text(), run_file.string() + ":/scene");
          options.potential = settings.potential;
          options.time_step = settings.time_step;
        }
        std::vector<std::filesystem::path> files;
        {
          py::gil_scoped_release release;
          files = post_process_run(run_file, options);
        }
        std::vector<std::string> names;
        names.reserve(files.size());
        for (const auto& f : files) names.push_back(f.string());
        return names;
      },
      py::arg("run_file"), py::arg("output"), py::arg("vtk"), py::arg("plots"), py::arg("every"), py::arg("bins"),
      py::arg("python"), py::arg("plots_script"));

  py::class_<VtkSeries>(m, "VtkSeries",
                        "A ParaView series (.vtp per snapshot, .pvd per kind) of a Simulation: VtkSeries(folder, sim); "
                        "write(sim) adds the current state and contacts")
      .def(py::init([](const std::filesystem::path& directory, const Simulation& simulation, double plane_size) {
             VtkSeriesOptions options;
             options.time_step = simulation.scene().run.step.integrator.time_step;
             options.plane_size = plane_size;
             return VtkSeries(directory, simulation.scene().model, options);
           }),
           py::arg("directory"), py::arg("simulation"), py::arg("plane_size") = 0.0,
           py::keep_alive<1, 3>())  // the series reads the simulation's model
      .def(
          "write",
          [](VtkSeries& series, const Simulation& simulation) {
            series.write(simulation.state(), simulation.contacts());
          },
          py::arg("simulation"), "Writes the simulation's current state and contacts as the next snapshot")
      .def_property_readonly(
          "collections",
          [](const VtkSeries& s) {
            std::vector<std::string> names;
            for (const auto& f : s.collections()) names.push_back(f.string());
            return names;
          },
          "the .pvd files written so far")
      .def_property_readonly("snapshot_count", &VtkSeries::snapshot_count, "snapshots written");

  // ---- FCLib ----
  m.def(
      "_fclib_read",
      [](const std::filesystem::path& path) {
        FclibFileInfo info;
        const LocalProblem problem = read_fclib_local(path, &info);
        py::dict d;
        d["indptr"] = py::array_t<int>(py::cast(problem.W.row_start));
        d["indices"] = py::array_t<int>(py::cast(problem.W.column));
        d["data"] = py::array_t<double>(py::cast(problem.W.value));
        d["shape"] = py::make_tuple(problem.W.rows, problem.W.columns);
        d["q"] = py::array_t<double>(py::cast(problem.q));
        d["mu"] = py::array_t<double>(py::cast(problem.mu));
        d["title"] = info.title;
        d["description"] = info.description;
        return d;
      },
      py::arg("path"));
  m.def(
      "_fclib_solve_file",
      [](const std::filesystem::path& path, double tolerance, int max_iterations, double relaxation,
         const std::string& order, std::uint64_t seed, const std::string& polish) {
        const LocalProblemOptions options = fclib_options(tolerance, max_iterations, relaxation, order, seed, polish);
        return solve_problem(read_fclib_local(path), options);
      },
      py::arg("path"), py::arg("tolerance"), py::arg("max_iterations"), py::arg("relaxation"), py::arg("order"),
      py::arg("seed"), py::arg("polish"));
  m.def(
      "_fclib_solve_csr",
      [](const py::array_t<int, py::array::c_style | py::array::forcecast>& indptr,
         const py::array_t<int, py::array::c_style | py::array::forcecast>& indices, const DoubleArray& data, int size,
         const DoubleArray& q, const DoubleArray& mu, double tolerance, int max_iterations, double relaxation,
         const std::string& order, std::uint64_t seed, const std::string& polish) {
        LocalProblem problem;
        const auto nc = static_cast<std::size_t>(mu.size());
        if (static_cast<std::size_t>(q.size()) != 3 * nc || static_cast<std::size_t>(size) != 3 * nc) {
          throw std::invalid_argument(
              fmt::format("W, q, mu: expected W of size 3 nc x 3 nc and |q| = 3 |mu|; got W {0}x{0}, "
                          "|q| = {1}, |mu| = {2}",
                          size, q.size(), mu.size()));
        }
        if (static_cast<std::size_t>(indptr.size()) != 3 * nc + 1 || indices.size() != data.size()) {
          throw std::invalid_argument(
              "W: malformed compressed-row arrays (indptr of 3 nc + 1 entries, indices and data alike)");
        }
        problem.W.rows = size;
        problem.W.columns = size;
        problem.W.row_start.assign(indptr.data(), indptr.data() + indptr.size());
        problem.W.column.assign(indices.data(), indices.data() + indices.size());
        problem.W.value.assign(data.data(), data.data() + data.size());
        for (std::size_t r = 0; r + 1 < problem.W.row_start.size(); ++r) {
          if (problem.W.row_start[r] > problem.W.row_start[r + 1])
            throw std::invalid_argument("W: indptr must not decrease");
        }
        if (problem.W.row_start.front() != 0 ||
            problem.W.row_start.back() != static_cast<int>(problem.W.value.size())) {
          throw std::invalid_argument("W: indptr must start at 0 and end at the number of stored values");
        }
        for (const int c : problem.W.column) {
          if (c < 0 || c >= size)
            throw std::invalid_argument(fmt::format("W: column index {} out of range [0, {})", c, size));
        }
        problem.q.assign(q.data(), q.data() + q.size());
        problem.mu.assign(mu.data(), mu.data() + mu.size());
        return solve_problem(problem, fclib_options(tolerance, max_iterations, relaxation, order, seed, polish));
      },
      py::arg("indptr"), py::arg("indices"), py::arg("data"), py::arg("size"), py::arg("q"), py::arg("mu"),
      py::arg("tolerance"), py::arg("max_iterations"), py::arg("relaxation"), py::arg("order"), py::arg("seed"),
      py::arg("polish"));
}

}  // namespace rubble::python
