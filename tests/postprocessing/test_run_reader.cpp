// The run file reader: what RunFile wrote comes back bit for bit (model, scene, series, snapshots),
// and files that are not rubble run files are refused with their path in the message.
#include "postprocessing/run_reader.hpp"

#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <fstream>

#include "postprocessing/run_file.hpp"
#include "test_shapes.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

fs::path scratch_dir() {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_run_reader";
  fs::create_directories(dir);
  return dir;
}

Model make_model() {
  Model model;
  model.materials = {{"basalt", 3000.0}, {"ice", 917.0}};
  model.contact_laws.reset(2, ContactLaw{0.3, 0.1});
  model.contact_laws.set(0, 1, ContactLaw{0.5, 0.0, 2.5, 0.125, 0.05, 0.02, 0.75});
  add_sphere(model, 0.5, 0);
  const Vec3 half(0.5, 0.25, 0.125);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half), 1);
  add_plane_wall(model, Vec3(0.0, 0.0, 1.0), 0);
  add_sphere(model, 0.25, 1);
  add_polyhedron(model, test::tetrahedron(0.4), test::tetrahedron_volume(0.4), Vec3::Constant(1e-3), 0);
  add_box_wall(model, Vec3(1.0, 2.0, 3.0), 1);
  return model;
}

TEST(RunReader, ReadsBackWhatWasWritten) {
  const fs::path path = scratch_dir() / "roundtrip.h5";
  const Model model = make_model();
  State state;
  state.resize(model.body_count());
  state.time = 0.75;
  state.step = 75;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    state.position[i] = Vec3(1.0 * i, -0.5 * i, 0.25);
    state.orientation[i] = Quat(Eigen::AngleAxisd(0.3 * i, Vec3::UnitY()));
    state.velocity[i] = Vec3(0.1, 0.2 * i, 0.3);
    state.angular_velocity[i] = Vec3(-0.1 * i, 0.0, 1.0);
  }
  ContactList contacts(1);
  contacts[0].id = {0, 3, 0, 0};
  contacts[0].point = Vec3(0.5, 0.5, 0.5);
  contacts[0].frame = frame_from_normal(Vec3(0.0, 0.6, 0.8));
  contacts[0].gap = -2e-4;
  contacts[0].impulse = Vec3(1.5, -0.25, 0.125);
  contacts[0].angular_impulse = Vec3(0.0625, -0.03125, 0.5);  // the model's laws resist rotation
  contacts[0].status = ContactStatus::sliding;
  const std::array<std::string_view, 2> stages{"detect", "solve"};
  {
    RunFile file = RunFile::create(path, model, "name = \"x\"\n", stages);
    for (int k = 1; k <= 10; ++k) {
      const std::array<double, 2> stage_seconds{0.1 * k, 0.2 * k};
      SeriesRow row;
      row.step = k;
      row.time = 0.01 * k;
      row.iterations = k;
      row.stage_seconds = stage_seconds;
      file.append_series(row);
    }
    file.write_snapshot(state, ContactList{});
    file.write_snapshot(state, contacts);
  }

  const RunReader reader = RunReader::open(path);
  EXPECT_EQ(reader.scene_text(), "name = \"x\"\n");
  const Model& m = reader.model();
  ASSERT_EQ(m.body_count(), model.body_count());
  EXPECT_EQ(m.shape_kind, model.shape_kind);
  EXPECT_EQ(m.shape_index, model.shape_index);
  EXPECT_EQ(m.material, model.material);
  EXPECT_EQ(m.mass, model.mass);
  EXPECT_EQ(m.inverse_mass, model.inverse_mass);
  EXPECT_EQ(m.volume, model.volume);
  EXPECT_EQ(m.bounding_radius, model.bounding_radius);
  EXPECT_EQ(m.principal_inertia, model.principal_inertia);
  EXPECT_EQ(m.inverse_inertia, model.inverse_inertia);
  ASSERT_EQ(m.spheres.size(), 2u);
  EXPECT_EQ(m.spheres[1].radius, 0.25);
  ASSERT_EQ(m.polyhedra.size(), 2u);
  for (std::size_t p = 0; p < 2; ++p) {
    EXPECT_EQ(m.polyhedra[p].vertices, model.polyhedra[p].vertices);
    EXPECT_EQ(m.polyhedra[p].faces, model.polyhedra[p].faces);
    EXPECT_EQ(m.polyhedra[p].face_normals, model.polyhedra[p].face_normals);
    EXPECT_EQ(m.polyhedra[p].edges.size(), model.polyhedra[p].edges.size());
  }
  EXPECT_EQ(m.planes[0].normal, Vec3::UnitZ());
  EXPECT_EQ(m.boxes[0].half_extents, Vec3(1.0, 2.0, 3.0));
  EXPECT_EQ(m.materials[1].name, "ice");
  EXPECT_EQ(m.contact_laws.get(1, 0).friction_coefficient, 0.5);
  EXPECT_EQ(m.contact_laws.get(1, 1).normal_restitution, 0.1);
  // Every parameter of the law comes back (rubble export writes the laws the run used).
  const ContactLaw& law = m.contact_laws.get(1, 0);
  EXPECT_EQ(law.cohesion, 2.5);
  EXPECT_EQ(law.work_of_adhesion, 0.125);
  EXPECT_EQ(law.rolling_friction, 0.05);
  EXPECT_EQ(law.twisting_friction, 0.02);
  EXPECT_EQ(law.tangential_restitution, 0.75);
  EXPECT_EQ(m.contact_laws.get(1, 1).cohesion, 0.0);

  const RunSeries series = reader.read_series();
  ASSERT_EQ(series.step.size(), 10u);
  EXPECT_EQ(series.iterations[9], 10);
  EXPECT_EQ(series.stage_names, (std::vector<std::string>{"detect", "solve"}));
  EXPECT_EQ(series.stage_seconds[1][4], 0.2 * 5);
  EXPECT_NEAR(reader.time_step(), 0.01, 1e-15);

  ASSERT_EQ(reader.snapshot_count(), 2u);
  EXPECT_TRUE(reader.read_snapshot(0).contacts.empty());
  const RunSnapshot snapshot = reader.read_snapshot(1);
  EXPECT_EQ(snapshot.state.time, 0.75);
  EXPECT_EQ(snapshot.state.step, 75);
  EXPECT_EQ(snapshot.state.position, state.position);
  EXPECT_EQ(snapshot.state.velocity, state.velocity);
  EXPECT_EQ(snapshot.state.angular_velocity, state.angular_velocity);
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    EXPECT_EQ(snapshot.state.orientation[i].coeffs(), state.orientation[i].coeffs());
  }
  ASSERT_EQ(snapshot.contacts.size(), 1u);
  const Contact& c = snapshot.contacts[0];
  EXPECT_EQ(c.id.body_a, 0u);
  EXPECT_EQ(c.id.body_b, 3u);
  EXPECT_EQ(c.point, contacts[0].point);
  EXPECT_EQ(c.frame, contacts[0].frame);
  EXPECT_EQ(c.gap, contacts[0].gap);
  EXPECT_EQ(c.impulse, contacts[0].impulse);
  EXPECT_EQ(c.angular_impulse, contacts[0].angular_impulse);
  EXPECT_EQ(c.status, ContactStatus::sliding);
  EXPECT_THROW(reader.read_snapshot(2), std::runtime_error);
}

/// A run file with one snapshot of one contact carrying `angular_impulse`, for `model`; then
/// reopened (as a resumed run does) and a second snapshot of the same contact appended.
RunReader written_and_resumed(const fs::path& path, const Model& model, const Vec3& angular_impulse) {
  State state;
  state.resize(model.body_count());
  ContactList contacts(1);
  contacts[0].id = {0, 3, 0, 0};
  contacts[0].frame = frame_from_normal(Vec3(0.0, 0.0, 1.0));
  contacts[0].impulse = Vec3(1.0, 0.0, 0.0);
  contacts[0].angular_impulse = angular_impulse;
  const std::array<std::string_view, 1> stages{"solve"};
  {
    RunFile file = RunFile::create(path, model, "", stages);
    const std::array<double, 1> stage_seconds{0.0};
    SeriesRow row;
    row.step = 1;
    row.stage_seconds = stage_seconds;
    file.append_series(row);
    file.write_snapshot(state, contacts);
  }
  {
    RunFile file = RunFile::reopen(path, 1, stages);
    state.step = 2;
    file.write_snapshot(state, contacts);
  }
  return RunReader::open(path);
}

// The rolling and twisting resistance's angular impulses are in the snapshots of a run whose laws
// resist rotation (written when the file is created and after a resume), and absent from a plain
// run's file (read back as zero: the solver never sets them there, and the file stays as it was).
TEST(RunReader, AngularImpulsesComeBackOnlyWhereALawResistsRotation) {
  const Vec3 held(0.0, -0.25, 0.125);
  const Model rolling = make_model();  // law (0, 1) has rolling and twisting friction
  const RunReader with = written_and_resumed(scratch_dir() / "rolling.h5", rolling, held);
  ASSERT_EQ(with.snapshot_count(), 2u);
  for (std::size_t k = 0; k < 2; ++k) EXPECT_EQ(with.read_snapshot(k).contacts.at(0).angular_impulse, held) << k;

  Model plain = make_model();
  plain.contact_laws.set(0, 1, ContactLaw{0.5, 0.0});
  const RunReader without = written_and_resumed(scratch_dir() / "plain.h5", plain, held);
  ASSERT_EQ(without.snapshot_count(), 2u);
  for (std::size_t k = 0; k < 2; ++k) EXPECT_EQ(without.read_snapshot(k).contacts.at(0).angular_impulse, Vec3::Zero());
}

TEST(RunReader, RefusesWhatIsNotARunFile) {
  const fs::path text = scratch_dir() / "not-hdf5.h5";
  std::ofstream(text) << "hello";
  for (const fs::path& path : {text, scratch_dir() / "missing.h5"}) {
    try {
      RunReader::open(path);
      FAIL() << "expected an exception for " << path;
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find(path.string()), std::string::npos) << error.what();
    }
  }
}

}  // namespace
}  // namespace rubble
