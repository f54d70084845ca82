// The VTK series, read back with VTK's own XML reader: point, cell and array counts and values
// match the state and contacts written; faces are wound counter-clockwise seen from outside; the
// .pvd collections list every file with its time.
#include "postprocessing/vtk_output.hpp"

#include <gtest/gtest.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkXMLPolyDataReader.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "test_shapes.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

vtkSmartPointer<vtkPolyData> read(const fs::path& path) {
  EXPECT_TRUE(fs::exists(path)) << path;
  vtkNew<vtkXMLPolyDataReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  EXPECT_EQ(reader->GetErrorCode(), 0u) << path;
  vtkSmartPointer<vtkPolyData> data = reader->GetOutput();
  return data;
}

Vec3 point_of(vtkPolyData* data, vtkIdType id) {
  Vec3 p;
  data->GetPoint(id, p.data());
  return p;
}

Vec3 tuple3(vtkDataArray* array, vtkIdType id) {
  Vec3 v;
  array->GetTuple(id, v.data());
  return v;
}

/// Newell's normal of polygon `cell` (not normalised) and its centroid.
std::pair<Vec3, Vec3> polygon_normal_and_centre(vtkPolyData* data, vtkIdType cell) {
  vtkNew<vtkIdList> ids;
  data->GetCellPoints(cell, ids);
  Vec3 normal = Vec3::Zero(), centre = Vec3::Zero();
  const vtkIdType count = ids->GetNumberOfIds();
  for (vtkIdType k = 0; k < count; ++k) {
    const Vec3 p = point_of(data, ids->GetId(k)), q = point_of(data, ids->GetId((k + 1) % count));
    normal += p.cross(q);
    centre += p / static_cast<double>(count);
  }
  return {normal, centre};
}

struct Scene {
  Model model;
  State state;
  ContactList contacts;
};

Scene make_scene() {
  Scene s;
  Model& model = s.model;
  model.materials = {{"rock", 2000.0}};
  model.contact_laws.reset(1, ContactLaw{});
  add_sphere(model, 0.5, 0);   // 0
  add_sphere(model, 0.25, 0);  // 1
  const Vec3 half(0.5, 0.25, 0.125);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half),
                 0);                                                                                      // 2
  add_polyhedron(model, test::tetrahedron(0.3), test::tetrahedron_volume(0.3), Vec3::Constant(1e-3), 0);  // 3
  add_plane_wall(model, Vec3::UnitZ(), 0);                                                                // 4
  add_box_wall(model, Vec3(1.0, 2.0, 3.0), 0);                                                            // 5
  s.state.resize(model.body_count());
  s.state.time = 0.5;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    s.state.position[i] = Vec3(1.5 * i, 0.25 * i, 1.0 + 0.1 * i);
    s.state.orientation[i] = Quat(Eigen::AngleAxisd(0.4 + 0.2 * i, Vec3(1.0, 2.0, -1.0).normalized()));
    s.state.velocity[i] = model.is_grain(i) ? Vec3(0.1 * i, -0.2, 0.3) : Vec3::Zero();
    s.state.angular_velocity[i] = model.is_grain(i) ? Vec3(1.0, 0.5 * i, -0.25) : Vec3::Zero();
  }
  s.state.position[4] = Vec3::Zero();
  s.contacts.resize(3);
  s.contacts[0].id = {0, 1, 0, 0};
  s.contacts[0].point = Vec3(0.7, 0.1, 1.05);
  s.contacts[0].frame = frame_from_normal(Vec3(1.0, 0.2, 0.1).normalized());
  s.contacts[0].impulse = Vec3(0.02, 0.005, -0.001);
  s.contacts[0].status = ContactStatus::sliding;
  s.contacts[0].gap = -1e-5;
  s.contacts[1].id = {4, 0, 0, 0};  // the plane wall under sphere 0
  s.contacts[1].point = Vec3(0.0, 0.0, 0.0);
  s.contacts[1].frame = frame_from_normal(Vec3::UnitZ());
  s.contacts[1].impulse = Vec3(0.5, 0.0, 0.0);
  s.contacts[1].status = ContactStatus::sticking;
  s.contacts[2].id = {2, 3, 1, 2};
  s.contacts[2].point = Vec3(3.7, 0.6, 1.25);
  s.contacts[2].frame = frame_from_normal(Vec3(0.0, 1.0, 0.0));
  s.contacts[2].impulse = Vec3(0.0, 0.0, 0.0);
  s.contacts[2].status = ContactStatus::open;
  return s;
}

TEST(VtkSeries, ReadBackWithVtkMatchesTheState) {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_vtk";
  fs::remove_all(dir);
  const Scene s = make_scene();
  const double h = 0.01;
  {
    VtkSeries series(dir, s.model, VtkSeriesOptions{h, 0.0, {}});
    series.write(s.state, s.contacts);
    State later = s.state;
    later.time = 1.5;
    series.write(later, ContactList{});
    EXPECT_EQ(series.snapshot_count(), 2u);
    EXPECT_EQ(series.collections().size(), 4u);
  }

  // Spheres: one point and one vertex cell per sphere, arrays per point.
  auto spheres = read(dir / "spheres_000000.vtp");
  ASSERT_EQ(spheres->GetNumberOfPoints(), 2);
  EXPECT_EQ(spheres->GetNumberOfVerts(), 2);
  for (vtkIdType k = 0; k < 2; ++k) {
    const auto body = static_cast<std::size_t>(spheres->GetPointData()->GetArray("body_id")->GetTuple1(k));
    EXPECT_EQ(body, static_cast<std::size_t>(k));
    EXPECT_EQ(point_of(spheres, k), s.state.position[body]);
    EXPECT_EQ(spheres->GetPointData()->GetArray("radius")->GetTuple1(k), s.model.sphere_radius(body));
    EXPECT_EQ(spheres->GetPointData()->GetArray("diameter")->GetTuple1(k), 2.0 * s.model.sphere_radius(body));
    EXPECT_EQ(tuple3(spheres->GetPointData()->GetArray("velocity"), k), s.state.velocity[body]);
    EXPECT_EQ(tuple3(spheres->GetPointData()->GetArray("angular_velocity"), k), s.state.angular_velocity[body]);
    EXPECT_EQ(spheres->GetPointData()->GetArray("coordination")->GetTuple1(k), 1.0);  // 0-1 carries force
  }

  // Polyhedra: 8 + 4 vertices, 6 + 4 faces, world positions x + R v, faces CCW from outside.
  auto polyhedra = read(dir / "polyhedra_000000.vtp");
  ASSERT_EQ(polyhedra->GetNumberOfPoints(), 12);
  ASSERT_EQ(polyhedra->GetNumberOfPolys(), 10);
  const ConvexPolyhedron& box = s.model.polyhedra[0];
  for (vtkIdType v = 0; v < 8; ++v) {
    const Vec3 expected = s.state.position[2] + s.state.orientation[2] * box.vertices[static_cast<std::size_t>(v)];
    EXPECT_NEAR((point_of(polyhedra, v) - expected).norm(), 0.0, 1e-14);
  }
  vtkDataArray* poly_body = polyhedra->GetCellData()->GetArray("body_id");
  for (vtkIdType f = 0; f < 10; ++f) {
    const auto body = static_cast<std::size_t>(poly_body->GetTuple1(f));
    EXPECT_EQ(body, f < 6 ? 2u : 3u);
    EXPECT_EQ(tuple3(polyhedra->GetCellData()->GetArray("velocity"), f), s.state.velocity[body]);
    const auto [normal, centre] = polygon_normal_and_centre(polyhedra, f);
    EXPECT_GT(normal.dot(centre - s.state.position[body]), 0.0) << "face " << f << " is wound inwards";
  }

  // Contacts: one line per point, between centres (to the contact point for the wall).
  auto network = read(dir / "contacts_000000.vtp");
  ASSERT_EQ(network->GetNumberOfLines(), 3);
  ASSERT_EQ(network->GetNumberOfPoints(), 6);
  EXPECT_EQ(point_of(network, 0), s.state.position[0]);
  EXPECT_EQ(point_of(network, 1), s.state.position[1]);
  EXPECT_EQ(point_of(network, 2), s.contacts[1].point);  // a = the wall
  EXPECT_EQ(point_of(network, 3), s.state.position[0]);
  vtkCellData* cells = network->GetCellData();
  for (vtkIdType k = 0; k < 3; ++k) {
    const Contact& c = s.contacts[static_cast<std::size_t>(k)];
    EXPECT_EQ(cells->GetArray("body_a")->GetTuple1(k), c.id.body_a);
    EXPECT_EQ(cells->GetArray("body_b")->GetTuple1(k), c.id.body_b);
    EXPECT_EQ(cells->GetArray("status")->GetTuple1(k), static_cast<double>(c.status));
    EXPECT_EQ(cells->GetArray("normal_impulse")->GetTuple1(k), c.impulse.x());
    EXPECT_NEAR(cells->GetArray("normal_force")->GetTuple1(k), c.impulse.x() / h, 1e-12);
    EXPECT_NEAR(cells->GetArray("tangential_force")->GetTuple1(k), c.impulse.tail<2>().norm() / h, 1e-12);
    const Vec3 world_force =
        (c.impulse.x() * c.frame.col(0) + c.impulse.y() * c.frame.col(1) + c.impulse.z() * c.frame.col(2)) / h;
    EXPECT_NEAR((tuple3(cells->GetArray("force"), k) - world_force).norm(), 0.0, 1e-12);
    EXPECT_EQ(tuple3(cells->GetArray("contact_point"), k), c.point);
  }
  auto empty = read(dir / "contacts_000001.vtp");
  EXPECT_EQ(empty->GetNumberOfCells(), 0);

  // Walls: a square for the plane, 6 faces for the box, wound outwards.
  auto walls = read(dir / "walls_000000.vtp");
  ASSERT_EQ(walls->GetNumberOfPolys(), 7);
  ASSERT_EQ(walls->GetNumberOfPoints(), 28);
  const auto [plane_normal, plane_centre] = polygon_normal_and_centre(walls, 0);
  EXPECT_NEAR((plane_normal.normalized() - s.state.orientation[4] * Vec3::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_NEAR((plane_centre - s.state.position[4]).norm(), 0.0, 1e-12);
  for (vtkIdType f = 1; f < 7; ++f) {
    EXPECT_EQ(walls->GetCellData()->GetArray("body_id")->GetTuple1(f), 5.0);
    const auto [normal, centre] = polygon_normal_and_centre(walls, f);
    EXPECT_GT(normal.dot(centre - s.state.position[5]), 0.0) << "box face " << f;
  }

  // Collections: every kind lists its two files with their times.
  for (const char* kind : {"spheres", "polyhedra", "contacts", "walls"}) {
    std::ifstream in(dir / (std::string(kind) + ".pvd"));
    std::stringstream text;
    text << in.rdbuf();
    const std::string pvd = text.str();
    const std::regex entry("<DataSet timestep=\"([^\"]+)\"[^>]*file=\"([^\"]+)\"");
    std::vector<std::pair<double, std::string>> entries;
    for (auto it = std::sregex_iterator(pvd.begin(), pvd.end(), entry); it != std::sregex_iterator(); ++it) {
      entries.emplace_back(std::stod((*it)[1]), (*it)[2]);
    }
    ASSERT_EQ(entries.size(), 2u) << kind;
    EXPECT_EQ(entries[0].first, 0.5);
    EXPECT_EQ(entries[1].first, 1.5);
    EXPECT_EQ(entries[1].second, std::string(kind) + "_000001.vtp");
    EXPECT_TRUE(fs::exists(dir / entries[1].second));
  }
}

// With rolling resistance in the law, the contact network also carries each point's angular impulse
// as a world vector on body b (frame times (m_n, m_t, m_s)) and its mean torque over h; without it,
// neither array is written (a plain run's files stay as they were).
TEST(VtkSeries, ContactsCarryTheResistingTorqueWhenALawResistsRotation) {
  const double h = 0.01;
  for (const double rolling_friction : {0.0, 0.05}) {
    const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_vtk_rolling";
    fs::remove_all(dir);
    Scene s = make_scene();
    ContactLaw law;
    law.rolling_friction = rolling_friction;
    s.model.contact_laws.reset(1, law);
    s.contacts[0].angular_impulse = Vec3(0.001, -0.002, 0.0005);
    {
      VtkSeries series(dir, s.model, VtkSeriesOptions{h, 0.0, {}});
      series.write(s.state, s.contacts);
    }
    const vtkSmartPointer<vtkPolyData> network = read(dir / "contacts_000000.vtp");
    vtkCellData* cells = network->GetCellData();
    if (rolling_friction == 0.0) {
      EXPECT_EQ(cells->GetArray("angular_impulse"), nullptr);
      EXPECT_EQ(cells->GetArray("resisting_torque"), nullptr);
      continue;
    }
    ASSERT_NE(cells->GetArray("angular_impulse"), nullptr);
    ASSERT_NE(cells->GetArray("resisting_torque"), nullptr);
    const Contact& c = s.contacts[0];
    const Vec3 world = c.angular_impulse.x() * c.frame.col(0) + c.angular_impulse.y() * c.frame.col(1) +
                       c.angular_impulse.z() * c.frame.col(2);
    EXPECT_NEAR((tuple3(cells->GetArray("angular_impulse"), 0) - world).norm(), 0.0, 1e-15);
    EXPECT_NEAR((tuple3(cells->GetArray("resisting_torque"), 0) - world / h).norm(), 0.0, 1e-13);
    EXPECT_EQ(tuple3(cells->GetArray("angular_impulse"), 1), Vec3::Zero());
  }
}

TEST(VtkSeries, UnwritableFolderThrowsWithThePath) {
  const Scene s = make_scene();
  EXPECT_THROW(VtkSeries("/proc/rubble-cannot-be-here", s.model), std::runtime_error);
}

}  // namespace
}  // namespace rubble
