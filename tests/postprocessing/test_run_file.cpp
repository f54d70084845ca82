// The run file writer: a small model with every shape kind, 2345 series rows (more than the
// 1000-row buffer, not a multiple of it), two snapshots (one with no contact, marked as the state
// at an interruption), two run parameters and the status. The file is checked
// by check_run_file.py with h5py against docs/output-format.md (layout: exactly the documented
// datasets and attributes, types, shapes) and against the values written here to a JSON file from
// the test's own objects (an independent path from the HDF5 writer).
#include "postprocessing/run_file.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>

#include "test_shapes.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::array<std::string_view, 3> stage_names{"detect", "solve", "update"};

json number(double x) {
  // JSON has no infinity: the checker reads "inf" back with float().
  if (std::isinf(x)) return x > 0 ? json("inf") : json("-inf");
  return json(x);
}

json vec3s(const std::vector<Vec3>& vectors) {
  json rows = json::array();
  for (const Vec3& v : vectors) rows.push_back({v.x(), v.y(), v.z()});
  return rows;
}

json doubles(const std::vector<double>& values) {
  json rows = json::array();
  for (double x : values) rows.push_back(number(x));
  return rows;
}

Model make_model() {
  Model model;
  model.materials = {{"basalt", 3000.0}, {"ice", 917.0}};
  model.contact_laws.reset(2, ContactLaw{0.3, 0.1});
  model.contact_laws.set(0, 1, ContactLaw{0.5, 0.0});
  add_sphere(model, 0.5, 0);
  const Vec3 half(0.5, 0.25, 0.125);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half), 1);
  add_plane_wall(model, Vec3(0.0, 0.0, 2.0), 0);
  add_sphere(model, 0.25, 1);
  add_polyhedron(model, test::tetrahedron(0.4), test::tetrahedron_volume(0.4), Vec3::Constant(1e-3), 0);
  add_box_wall(model, Vec3(1.0, 2.0, 3.0), 1);
  return model;
}

State make_state(const Model& model, double time, std::int64_t step) {
  State state;
  state.resize(model.body_count());
  state.time = time;
  state.step = step;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    const double k = static_cast<double>(i) + time;
    state.position[i] = Vec3(k, 2.0 * k, -k);
    state.orientation[i] = Quat(Eigen::AngleAxisd(0.1 * k, Vec3(1.0, 2.0, 3.0).normalized()));
    state.velocity[i] = Vec3(0.5 * k, 0.25, -0.125 * k);
    state.angular_velocity[i] = Vec3(-k, 0.0, 3.0 * k);
  }
  return state;
}

ContactList make_contacts() {
  ContactList contacts(2);
  contacts[0].id = {0, 1, 0, 3};
  contacts[0].point = Vec3(0.1, 0.2, 0.3);
  contacts[0].frame = frame_from_normal(Vec3(1.0, 1.0, 0.0).normalized());
  contacts[0].gap = -1e-4;
  contacts[0].impulse = Vec3(2.0, 0.5, -0.25);
  contacts[0].status = ContactStatus::sticking;
  contacts[1].id = {3, 2, 0, 0};
  contacts[1].point = Vec3(-1.0, 0.0, 1.0);
  contacts[1].frame = frame_from_normal(Vec3(0.0, 0.0, -1.0));
  contacts[1].gap = 2e-3;
  contacts[1].impulse = Vec3(0.0, 0.0, 0.0);
  contacts[1].status = ContactStatus::open;
  return contacts;
}

json snapshot_json(const State& state, const ContactList& contacts) {
  json s;
  s["time"] = state.time;
  s["step"] = state.step;
  s["position"] = vec3s(state.position);
  json orientation = json::array();
  for (const Quat& q : state.orientation) orientation.push_back({q.w(), q.x(), q.y(), q.z()});
  s["orientation"] = orientation;
  s["velocity"] = vec3s(state.velocity);
  s["angular_velocity"] = vec3s(state.angular_velocity);
  json a = json::array(), b = json::array(), gap = json::array(), status = json::array();
  std::vector<Vec3> point, normal, t, s_axis, impulse;
  for (const Contact& c : contacts) {
    a.push_back(c.id.body_a);
    b.push_back(c.id.body_b);
    gap.push_back(c.gap);
    status.push_back(static_cast<int>(c.status));
    point.push_back(c.point);
    normal.push_back(c.frame.col(0));
    t.push_back(c.frame.col(1));
    s_axis.push_back(c.frame.col(2));
    impulse.push_back(c.impulse);
  }
  s["contact_body_a"] = a;
  s["contact_body_b"] = b;
  s["contact_point"] = vec3s(point);
  s["contact_normal"] = vec3s(normal);
  s["contact_tangent_t"] = vec3s(t);
  s["contact_tangent_s"] = vec3s(s_axis);
  s["contact_impulse"] = vec3s(impulse);
  s["contact_gap"] = gap;
  s["contact_status"] = status;
  return s;
}

std::string run_checker(const fs::path& run, const fs::path& expected) {
  const std::string command = std::string("/usr/bin/python3 ") + RUBBLE_CHECK_RUN_FILE_SCRIPT + " " + run.string() +
                              " " + expected.string() + " " + RUBBLE_OUTPUT_FORMAT_DOC;
  return command;
}

TEST(RunFile, WritesTheDocumentedLayoutAndValues) {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_run_file";
  fs::create_directories(dir);
  const fs::path run = dir / "run.h5";
  const fs::path expected_path = dir / "expected.json";
  const Model model = make_model();
  const std::string scene = "name = \"test\"\n[run]\nend_time = 1.0 # ünïcode\n";
  constexpr int rows = 2345;

  json expected;
  const State first = make_state(model, 0.5, 500);
  const ContactList contacts = make_contacts();
  const State second = make_state(model, 1.25, 1250);
  {
    const std::vector<RunParameter> parameters{{"time_step", 1e-3, "s", true}, {"rest_duration", 2.5, "s", false}};
    RunFile file = RunFile::create(run, model, scene, stage_names, parameters);
    for (int k = 0; k < rows; ++k) {
      const std::array<double, 3> stages{1e-6 * k, 2e-6 * k, 3e-6 * k + 1.0};
      SeriesRow row;
      row.step = k + 1;
      row.time = 1e-3 * (k + 1);
      row.kinetic_energy = 0.5 * k;
      row.contacts = k % 7;
      row.active_contacts = k % 5;
      row.iterations = k % 13;
      row.residual = 1.0 / (k + 1);
      row.wall_seconds = 1e-4 * k;
      row.stage_seconds = stages;
      file.append_series(row);
    }
    file.write_snapshot(first, contacts);
    file.write_snapshot(second, ContactList{}, true);  // as at a stop by signal
    file.set_status(RunStatus::interrupted);
    EXPECT_EQ(file.snapshot_count(), 2);
    EXPECT_EQ(file.snapshot_times(), (std::vector<double>{0.5, 1.25}));
    EXPECT_EQ(file.last_snapshot_step(), 1250);
    EXPECT_EQ(file.series_rows(), rows);
    RunFile moved = std::move(file);  // the moved-to object owns the file; no flush(): the destructor writes
  }

  // What the test gave the writer, from its own objects.
  const std::size_t n = model.body_count();
  expected["scene"] = scene;
  expected["stage_names"] = {"detect", "solve", "update"};
  expected["model_attributes"] = {{"body_count", n}, {"grain_count", 4}};
  std::size_t vertices = 0, faces = 0, face_vertices = 0;
  json& d = expected["datasets"];
  std::vector<Vec3> all_vertices, face_normals;
  json vertex_offset = {0}, face_offset = {0}, polyhedron_face_offset = {0}, face_vertex_list = json::array();
  for (const ConvexPolyhedron& p : model.polyhedra) {
    all_vertices.insert(all_vertices.end(), p.vertices.begin(), p.vertices.end());
    vertices += p.vertices.size();
    vertex_offset.push_back(vertices);
    for (std::size_t f = 0; f < p.faces.size(); ++f) {
      for (int v : p.faces[f]) face_vertex_list.push_back(v);
      face_vertices += p.faces[f].size();
      face_offset.push_back(face_vertices);
      face_normals.push_back(p.face_normals[f]);
    }
    faces += p.faces.size();
    polyhedron_face_offset.push_back(faces);
  }
  expected["sizes"] = {{"N", n},
                       {"P", model.polyhedra.size()},
                       {"V", vertices},
                       {"F", faces},
                       {"K", face_vertices},
                       {"W", 1},
                       {"B", 1},
                       {"M", 2},
                       {"S", rows}};
  d["/model/body_shape_kind"] = {0, 1, 2, 0, 1, 3};
  d["/model/body_shape_index"] = {0, 0, 0, 1, 1, 0};
  d["/model/material"] = {0, 1, 0, 1, 0, 1};
  d["/model/mass"] = doubles(model.mass);
  d["/model/volume"] = doubles(model.volume);
  d["/model/bounding_radius"] = {0.5,  Vec3(0.5, 0.25, 0.125).norm(), "inf",
                                 0.25, model.bounding_radius[4],      Vec3(1, 2, 3).norm()};
  d["/model/radius"] = {0.5, 0.0, 0.0, 0.25, 0.0, 0.0};
  d["/model/principal_inertia"] = vec3s(model.principal_inertia);
  d["/model/polyhedra/vertices"] = vec3s(all_vertices);
  d["/model/polyhedra/vertex_offset"] = vertex_offset;
  d["/model/polyhedra/face_vertices"] = face_vertex_list;
  d["/model/polyhedra/face_offset"] = face_offset;
  d["/model/polyhedra/polyhedron_face_offset"] = polyhedron_face_offset;
  d["/model/polyhedra/face_normal"] = vec3s(face_normals);
  d["/model/planes/normal"] = {{0.0, 0.0, 1.0}};
  d["/model/boxes/half_extents"] = {{1.0, 2.0, 3.0}};
  d["/model/materials/name"] = {"basalt", "ice"};
  d["/model/materials/density"] = {3000.0, 917.0};
  d["/model/contact_laws/friction"] = {{0.3, 0.5}, {0.5, 0.3}};
  d["/model/contact_laws/restitution"] = {{0.1, 0.0}, {0.0, 0.1}};
  for (const char* column : {"step", "time", "kinetic_energy", "contacts", "active_contacts", "iterations", "residual",
                             "wall_seconds", "stage_seconds/detect", "stage_seconds/solve", "stage_seconds/update"}) {
    d[std::string("/series/") + column] = json::array();
  }
  for (int k = 0; k < rows; ++k) {
    d["/series/step"].push_back(k + 1);
    d["/series/time"].push_back(1e-3 * (k + 1));
    d["/series/kinetic_energy"].push_back(0.5 * k);
    d["/series/contacts"].push_back(k % 7);
    d["/series/active_contacts"].push_back(k % 5);
    d["/series/iterations"].push_back(k % 13);
    d["/series/residual"].push_back(1.0 / (k + 1));
    d["/series/wall_seconds"].push_back(1e-4 * k);
    d["/series/stage_seconds/detect"].push_back(1e-6 * k);
    d["/series/stage_seconds/solve"].push_back(2e-6 * k);
    d["/series/stage_seconds/update"].push_back(3e-6 * k + 1.0);
  }
  expected["snapshots"] = {snapshot_json(first, contacts), snapshot_json(second, ContactList{})};
  expected["snapshots"][1]["interrupted"] = 1;
  expected["status"] = "interrupted";
  expected["run"] = {{"time_step", {1e-3, "s", "auto"}}, {"rest_duration", {2.5, "s", "scene"}}};
  std::ofstream(expected_path) << expected.dump();  // shortest round-trip form of every double

  const std::string command = run_checker(run, expected_path);
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
}

TEST(RunFile, CannotCreateNamesThePath) {
  const Model model = make_model();
  const fs::path bad = "/nonexistent-rubble-dir/sub/run.h5";
  try {
    RunFile::create(bad, model, "", stage_names);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(bad.string()), std::string::npos) << error.what();
  }
}

TEST(RunFile, RejectsMismatchedInput) {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_run_file";
  fs::create_directories(dir);
  const Model model = make_model();
  constexpr std::array<std::string_view, 2> duplicated{"a", "a"};
  EXPECT_THROW(RunFile::create(dir / "bad.h5", model, "", duplicated), std::invalid_argument);
  constexpr std::array<std::string_view, 1> slash{"a/b"};
  EXPECT_THROW(RunFile::create(dir / "bad.h5", model, "", slash), std::invalid_argument);

  RunFile file = RunFile::create(dir / "mismatch.h5", model, "", stage_names);
  const std::array<double, 2> two_stages{0.0, 0.0};
  SeriesRow row;
  row.stage_seconds = two_stages;
  EXPECT_THROW(file.append_series(row), std::invalid_argument);
  State state;
  state.resize(model.body_count() - 1);
  EXPECT_THROW(file.write_snapshot(state, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rubble

namespace rubble {
namespace {

TEST(RunFile, DiskFullThrowsWithThePath) {
  // /dev/full accepts the open and fails every write with ENOSPC, like a full disk. HDF5 then
  // cannot close the file (closing flushes), and keeps it until the process ends; so the scenario
  // runs in a child process that leaves with _exit: 0 if the error named the file, 1 otherwise.
  if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        const Model model = make_model();
        State state;
        state.resize(model.body_count());
        try {
          RunFile file = RunFile::create("/dev/full", model, "", stage_names);
          for (int k = 0; k < 20; ++k) file.write_snapshot(state, {});
          file.flush();
        } catch (const std::runtime_error& error) {
          std::fprintf(stderr, "%s\n", error.what());
          _exit(std::string(error.what()).find("/dev/full") != std::string::npos ? 0 : 1);
        }
        _exit(1);
      },
      ::testing::ExitedWithCode(0), "/dev/full");
}

}  // namespace
}  // namespace rubble
