#include "postprocessing/vtk_output.hpp"

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDoubleArray.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkXMLPolyDataWriter.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "postprocessing/metrics.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

vtkSmartPointer<vtkDoubleArray> vector_array(const char* name) {
  auto array = vtkSmartPointer<vtkDoubleArray>::New();
  array->SetName(name);
  array->SetNumberOfComponents(3);
  return array;
}

vtkSmartPointer<vtkDoubleArray> scalar_array(const char* name) {
  auto array = vtkSmartPointer<vtkDoubleArray>::New();
  array->SetName(name);
  return array;
}

vtkSmartPointer<vtkIntArray> int_array(const char* name) {
  auto array = vtkSmartPointer<vtkIntArray>::New();
  array->SetName(name);
  return array;
}

void write_polydata(vtkPolyData* data, const fs::path& path) {
  vtkNew<vtkXMLPolyDataWriter> writer;
  writer->SetFileName(path.c_str());
  writer->SetInputData(data);
  writer->SetDataModeToAppended();
  writer->EncodeAppendedDataOff();  // raw binary, not base64
  writer->SetCompressorTypeToZLib();
  if (writer->Write() != 1) throw std::runtime_error(path.string() + ": cannot write the VTK file");
}

/// Adds the quadrilateral of a square of side `size` centred on `centre`, normal `normal`.
void add_square(vtkPoints* points, vtkCellArray* polygons, const Vec3& centre, const Vec3& normal, double size) {
  const Mat3 frame = frame_from_normal(normal.normalized());
  const Vec3 u = 0.5 * size * frame.col(1), v = 0.5 * size * frame.col(2);
  const std::array<Vec3, 4> corners{centre - u - v, centre + u - v, centre + u + v, centre - u + v};
  std::array<vtkIdType, 4> ids{};
  for (std::size_t k = 0; k < 4; ++k) ids[k] = points->InsertNextPoint(corners[k].data());
  polygons->InsertNextCell(4, ids.data());
}

/// spheres_NNNNNN.vtp: one point (vertex cell) per sphere, with its radius and diameter (the glyph
/// scale), velocities and coordination.
void write_spheres(const Model& model, const State& state, const std::vector<int>& coordination, const fs::path& path) {
  vtkNew<vtkPolyData> data;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  vtkNew<vtkCellArray> vertices;
  auto body = int_array("body_id"), contacts_per_grain = int_array("coordination");
  auto radius = scalar_array("radius"), diameter = scalar_array("diameter");
  auto velocity = vector_array("velocity"), angular_velocity = vector_array("angular_velocity");
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (model.shape_kind[i] != ShapeKind::sphere) continue;
    const vtkIdType id = points->InsertNextPoint(state.position[i].data());
    vertices->InsertNextCell(1, &id);
    body->InsertNextValue(static_cast<int>(i));
    contacts_per_grain->InsertNextValue(coordination[i]);
    radius->InsertNextValue(model.sphere_radius(i));
    diameter->InsertNextValue(2.0 * model.sphere_radius(i));
    velocity->InsertNextTuple(state.velocity[i].data());
    angular_velocity->InsertNextTuple(state.angular_velocity[i].data());
  }
  data->SetPoints(points);
  data->SetVerts(vertices);
  for (vtkDataArray* array :
       std::initializer_list<vtkDataArray*>{body, contacts_per_grain, radius, diameter, velocity, angular_velocity}) {
    data->GetPointData()->AddArray(array);
  }
  data->GetPointData()->SetActiveScalars("diameter");  // glyph scale by default
  write_polydata(data, path);
}

/// polyhedra_NNNNNN.vtp: every face of every polyhedron as a polygon, in world coordinates, each
/// carrying its body's id, velocities and coordination.
void write_polyhedra(const Model& model, const State& state, const std::vector<int>& coordination,
                     const fs::path& path) {
  vtkNew<vtkPolyData> data;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  vtkNew<vtkCellArray> polygons;
  auto body = int_array("body_id"), contacts_per_grain = int_array("coordination");
  auto velocity = vector_array("velocity"), angular_velocity = vector_array("angular_velocity");
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (model.shape_kind[i] != ShapeKind::polyhedron) continue;
    const ConvexPolyhedron& shape = model.polyhedra[static_cast<std::size_t>(model.shape_index[i])];
    const Mat3 rotation = state.orientation[i].toRotationMatrix();
    const vtkIdType first = points->GetNumberOfPoints();
    for (const Vec3& vertex : shape.vertices) {
      const Vec3 world = state.position[i] + rotation * vertex;
      points->InsertNextPoint(world.data());
    }
    for (const std::span<const int> face : shape.faces) {
      std::vector<vtkIdType> ids;
      for (int v : face) ids.push_back(first + v);
      polygons->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
      body->InsertNextValue(static_cast<int>(i));
      contacts_per_grain->InsertNextValue(coordination[i]);
      velocity->InsertNextTuple(state.velocity[i].data());
      angular_velocity->InsertNextTuple(state.angular_velocity[i].data());
    }
  }
  data->SetPoints(points);
  data->SetPolys(polygons);
  for (vtkDataArray* array :
       std::initializer_list<vtkDataArray*>{body, contacts_per_grain, velocity, angular_velocity}) {
    data->GetCellData()->AddArray(array);
  }
  write_polydata(data, path);
}

/// contacts_NNNNNN.vtp: the contact network, one line per contact point from grain centre to grain
/// centre (to the contact point for a wall), with its impulses, and its mean forces impulse / h
/// when the time step h is known (h > 0); with rolling or twisting resistance in a law, also the
/// angular impulse and its mean torque.
void write_contacts(const Model& model, const State& state, const ContactList& contacts, double h,
                    const fs::path& path) {
  vtkNew<vtkPolyData> data;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  vtkNew<vtkCellArray> lines;
  auto body_a = int_array("body_a"), body_b = int_array("body_b"), status = int_array("status");
  auto normal_impulse = scalar_array("normal_impulse"), tangential_impulse = scalar_array("tangential_impulse");
  auto normal_force = scalar_array("normal_force"), tangential_force = scalar_array("tangential_force");
  auto force = vector_array("force"), normal = vector_array("normal"), point = vector_array("contact_point");
  auto gap = scalar_array("gap");
  // Rolling and twisting resistance (world vectors on body b): only where a law has them.
  const bool resisted_rotation = model.contact_laws.any_resists_rotation();
  auto angular_impulse = vector_array("angular_impulse"), resisting_torque = vector_array("resisting_torque");
  for (const Contact& contact : contacts) {
    const std::size_t a = contact.id.body_a, b = contact.id.body_b;
    const Vec3 from = model.is_grain(a) ? state.position[a] : contact.point;
    const Vec3 to = model.is_grain(b) ? state.position[b] : contact.point;
    const std::array<vtkIdType, 2> ids{points->InsertNextPoint(from.data()), points->InsertNextPoint(to.data())};
    lines->InsertNextCell(2, ids.data());
    body_a->InsertNextValue(static_cast<int>(a));
    body_b->InsertNextValue(static_cast<int>(b));
    status->InsertNextValue(static_cast<int>(contact.status));
    const double r_n = contact.impulse.x();
    const double r_t = contact.impulse.tail<2>().norm();
    normal_impulse->InsertNextValue(r_n);
    tangential_impulse->InsertNextValue(r_t);
    const Vec3 world_impulse = contact.frame * contact.impulse;  // on body b
    const Vec3 mean_force = h > 0.0 ? Vec3(world_impulse / h) : Vec3::Zero();
    normal_force->InsertNextValue(h > 0.0 ? r_n / h : 0.0);
    tangential_force->InsertNextValue(h > 0.0 ? r_t / h : 0.0);
    force->InsertNextTuple(mean_force.data());
    const Vec3 n_world = contact.frame.col(0);
    normal->InsertNextTuple(n_world.data());
    point->InsertNextTuple(contact.point.data());
    gap->InsertNextValue(contact.gap);
    if (resisted_rotation) {
      const Vec3 world_angular = contact.frame * contact.angular_impulse;
      const Vec3 mean_torque = h > 0.0 ? Vec3(world_angular / h) : Vec3::Zero();
      angular_impulse->InsertNextTuple(world_angular.data());
      resisting_torque->InsertNextTuple(mean_torque.data());
    }
  }
  data->SetPoints(points);
  data->SetLines(lines);
  for (vtkDataArray* array : std::initializer_list<vtkDataArray*>{body_a, body_b, status, normal_impulse,
                                                                  tangential_impulse, gap, normal, point}) {
    data->GetCellData()->AddArray(array);
  }
  if (h > 0.0) {
    for (vtkDataArray* array : std::initializer_list<vtkDataArray*>{normal_force, tangential_force, force}) {
      data->GetCellData()->AddArray(array);
    }
  }
  if (resisted_rotation) {
    data->GetCellData()->AddArray(angular_impulse);
    if (h > 0.0) data->GetCellData()->AddArray(resisting_torque);
  }
  write_polydata(data, path);
}

/// Side of the square drawn for plane wall `wall`: `requested` if positive, else twice the largest
/// distance from the plane's point to a grain's bounding sphere (1 m without grains).
double plane_square_size(const Model& model, const State& state, std::size_t wall, double requested) {
  double size = requested;
  if (size > 0.0) return size;
  for (std::size_t g = 0; g < model.body_count(); ++g) {
    if (model.is_grain(g))
      size = std::max(size, 2.0 * ((state.position[g] - state.position[wall]).norm() + model.bounding_radius[g]));
  }
  return size <= 0.0 ? 1.0 : size;
}

/// Adds the six faces of box wall `wall` as quadrilaterals, each counter-clockwise seen from outside.
void add_box_faces(vtkPoints* points, vtkCellArray* polygons, vtkIntArray* body, const Model& model, const State& state,
                   std::size_t wall) {
  const Mat3 rotation = state.orientation[wall].toRotationMatrix();
  const Vec3& h = model.boxes[static_cast<std::size_t>(model.shape_index[wall])].half_extents;
  for (int axis = 0; axis < 3; ++axis) {
    for (const double side : {-1.0, 1.0}) {
      // Face `side` along `axis`: centre at side * h[axis], spanned by the two other axes.
      const int u_axis = (axis + 1) % 3, v_axis = (axis + 2) % 3;
      Vec3 centre = Vec3::Zero();
      centre[axis] = side * h[axis];
      Vec3 u = Vec3::Zero(), v = Vec3::Zero();
      u[u_axis] = h[u_axis];
      v[v_axis] = side * h[v_axis];  // flips the winding so that every face is CCW from outside
      const std::array<Vec3, 4> corners{centre - u - v, centre + u - v, centre + u + v, centre - u + v};
      std::array<vtkIdType, 4> ids{};
      for (std::size_t k = 0; k < 4; ++k) {
        const Vec3 world = state.position[wall] + rotation * corners[k];
        ids[k] = points->InsertNextPoint(world.data());
      }
      polygons->InsertNextCell(4, ids.data());
      body->InsertNextValue(static_cast<int>(wall));
    }
  }
}

/// walls_NNNNNN.vtp: a square of side `plane_size` (VtkSeriesOptions) per plane wall, the six faces
/// of each box wall.
void write_walls(const Model& model, const State& state, double plane_size, const fs::path& path) {
  vtkNew<vtkPolyData> data;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  vtkNew<vtkCellArray> polygons;
  auto body = int_array("body_id");
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (model.is_grain(i)) continue;
    if (model.shape_kind[i] == ShapeKind::plane) {
      const Mat3 rotation = state.orientation[i].toRotationMatrix();
      const Vec3& normal = model.planes[static_cast<std::size_t>(model.shape_index[i])].normal;
      add_square(points, polygons, state.position[i], rotation * normal,
                 plane_square_size(model, state, i, plane_size));
      body->InsertNextValue(static_cast<int>(i));
    } else if (model.shape_kind[i] == ShapeKind::box) {
      add_box_faces(points, polygons, body, model, state, i);
    }
  }
  data->SetPoints(points);
  data->SetPolys(polygons);
  data->GetCellData()->AddArray(body);
  write_polydata(data, path);
}

}  // namespace

struct VtkSeries::Impl {
  fs::path directory;
  const Model* model = nullptr;
  VtkSeriesOptions options;
  bool has_spheres = false, has_polyhedra = false, has_walls = false;
  std::vector<double> times;
  // kind -> its .pvd entries are KIND_NNNNNN.vtp for every time
  std::vector<std::string> kinds;

  fs::path file_of(const std::string& kind, std::size_t index) const {
    std::array<char, 16> number{};
    std::snprintf(number.data(), number.size(), "%06zu", index);
    return directory / (kind + "_" + number.data() + ".vtp");
  }

  void write_collections() const {
    for (const std::string& kind : kinds) {
      const fs::path path = directory / (kind + ".pvd");
      std::ofstream out(path);
      out.precision(17);
      out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
          << "  <Collection>\n";
      for (std::size_t k = 0; k < times.size(); ++k) {
        out << "    <DataSet timestep=\"" << times[k] << "\" group=\"\" part=\"0\" file=\""
            << file_of(kind, k).filename().string() << "\"/>\n";
      }
      out << "  </Collection>\n</VTKFile>\n";
      if (!out) throw std::runtime_error(path.string() + ": cannot write the ParaView collection");
    }
  }
};

VtkSeries::VtkSeries(const fs::path& directory, const Model& model, const VtkSeriesOptions& options)
    : impl_(std::make_unique<Impl>()) {
  std::error_code error;
  fs::create_directories(directory, error);
  if (error) throw std::runtime_error(directory.string() + ": cannot create the folder: " + error.message());
  impl_->directory = directory;
  impl_->model = &model;
  impl_->options = options;
  impl_->times = options.earlier_times;
  // By the shape tables, which hold every grain's shape: a run with an inflow hands over the
  // model of the bodies in play, which gains the inflow's grains (of the same tables) later.
  impl_->has_spheres = !model.spheres.empty();
  impl_->has_polyhedra = !model.polyhedra.empty();
  for (std::size_t i = 0; i < model.body_count(); ++i) impl_->has_walls |= !model.is_grain(i);
  if (impl_->has_spheres) impl_->kinds.push_back("spheres");
  if (impl_->has_polyhedra) impl_->kinds.push_back("polyhedra");
  impl_->kinds.push_back("contacts");
  if (impl_->has_walls) impl_->kinds.push_back("walls");
}

VtkSeries::VtkSeries(VtkSeries&&) noexcept = default;
VtkSeries& VtkSeries::operator=(VtkSeries&&) noexcept = default;
VtkSeries::~VtkSeries() = default;

std::vector<fs::path> VtkSeries::collections() const {
  std::vector<fs::path> paths;
  if (impl_->times.empty()) return paths;
  for (const std::string& kind : impl_->kinds) paths.push_back(impl_->directory / (kind + ".pvd"));
  return paths;
}

std::size_t VtkSeries::snapshot_count() const { return impl_->times.size(); }

void VtkSeries::write(const State& state, const ContactList& contacts) {
  const Model& model = *impl_->model;
  const std::size_t index = impl_->times.size();
  const std::size_t n = model.body_count();
  if (state.body_count() != n) {
    throw std::invalid_argument(impl_->directory.string() + ": VTK snapshot of a state with " +
                                std::to_string(state.body_count()) + " bodies, the model has " + std::to_string(n));
  }
  const std::vector<int> coordination = grain_contact_counts(model, contacts);
  if (impl_->has_spheres) write_spheres(model, state, coordination, impl_->file_of("spheres", index));
  if (impl_->has_polyhedra) write_polyhedra(model, state, coordination, impl_->file_of("polyhedra", index));
  write_contacts(model, state, contacts, impl_->options.time_step, impl_->file_of("contacts", index));
  if (impl_->has_walls) write_walls(model, state, impl_->options.plane_size, impl_->file_of("walls", index));
  impl_->times.push_back(state.time);
  impl_->write_collections();
}

}  // namespace rubble
