#include "postprocessing/run_file_datasets.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "postprocessing/run_file.hpp"

namespace rubble::run_file_detail {
namespace {

using hdf5::Handle;
namespace fs = std::filesystem;

/// Flattens n 3-vectors into an n x 3 row-major array.
std::vector<double> flatten(std::span<const Vec3> vectors) {
  std::vector<double> flat;
  flat.reserve(3 * vectors.size());
  for (const Vec3& v : vectors) flat.insert(flat.end(), {v.x(), v.y(), v.z()});
  return flat;
}

void write_vec3s(hid_t parent, const std::string& name, std::span<const Vec3> vectors, std::string_view unit,
                 const fs::path& file) {
  const std::array<hsize_t, 2> dims{vectors.size(), 3};
  hdf5::write_doubles(parent, name, flatten(vectors), dims, file, storage);
  units(parent, name, unit, file);
}

void write_column(hid_t parent, const std::string& name, std::span<const double> values, std::string_view unit,
                  const fs::path& file) {
  const std::array<hsize_t, 1> dims{values.size()};
  hdf5::write_doubles(parent, name, values, dims, file, storage);
  units(parent, name, unit, file);
}

/// The integer datasets of the model and the snapshots: ids, indices, kinds, counts (units "1").
template <typename Write, typename Values>
void write_integers(Write write, hid_t parent, const std::string& name, const Values& values,
                    std::span<const hsize_t> dims, const fs::path& file) {
  write(parent, name, values, dims, file, storage);
  units(parent, name, "1", file);
}

/// /model@body_count, @grain_count and one row per body: shape kind and index, material, mass,
/// volume, bounding radius, radius (0 unless a sphere), principal moments of inertia.
void write_bodies(hid_t g, const Model& model, const fs::path& file) {
  const std::size_t n = model.body_count();
  hdf5::write_attribute(g, "body_count", static_cast<std::int64_t>(n), file);
  std::int64_t grains = 0;
  for (std::size_t i = 0; i < n; ++i) grains += model.is_grain(i) ? 1 : 0;
  hdf5::write_attribute(g, "grain_count", grains, file);

  std::vector<std::int8_t> kind(n);
  std::vector<std::int32_t> shape_index(n), material(n);
  std::vector<double> radius(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    kind[i] = static_cast<std::int8_t>(model.shape_kind[i]);
    shape_index[i] = model.shape_index[i];
    material[i] = model.material[i];
    if (model.shape_kind[i] == ShapeKind::sphere) radius[i] = model.sphere_radius(i);
  }
  const std::array<hsize_t, 1> dims_n{n};
  write_integers(hdf5::write_int8s, g, "body_shape_kind", kind, dims_n, file);
  write_integers(hdf5::write_int32s, g, "body_shape_index", shape_index, dims_n, file);
  write_integers(hdf5::write_int32s, g, "material", material, dims_n, file);
  write_column(g, "mass", model.mass, "kg", file);
  write_column(g, "volume", model.volume, "m^3", file);
  write_column(g, "bounding_radius", model.bounding_radius, "m", file);
  write_column(g, "radius", radius, "m", file);
  write_vec3s(g, "principal_inertia", model.principal_inertia, "kg m^2", file);
}

/// /model/polyhedra as flat arrays (CSR-like): polyhedron p owns vertices
/// [vertex_offset[p], vertex_offset[p+1]) and faces [polyhedron_face_offset[p], ...[p+1]);
/// face f lists face_vertices[face_offset[f] .. face_offset[f+1]), indices local to its polyhedron.
void write_polyhedra(hid_t g, const Model& model, const fs::path& file) {
  Handle polyhedra = hdf5::create_group(g, "polyhedra", file);
  std::vector<Vec3> vertices, face_normals;
  std::vector<std::int64_t> vertex_offset{0}, face_offset{0}, polyhedron_face_offset{0};
  std::vector<std::int32_t> face_vertices;
  for (const ConvexPolyhedron& shape : model.polyhedra) {
    vertices.insert(vertices.end(), shape.vertices.begin(), shape.vertices.end());
    vertex_offset.push_back(static_cast<std::int64_t>(vertices.size()));
    for (std::size_t f = 0; f < shape.faces.size(); ++f) {
      face_vertices.insert(face_vertices.end(), shape.faces[f].begin(), shape.faces[f].end());
      face_offset.push_back(static_cast<std::int64_t>(face_vertices.size()));
      face_normals.push_back(f < shape.face_normals.size() ? shape.face_normals[f] : Vec3::Zero());
    }
    polyhedron_face_offset.push_back(static_cast<std::int64_t>(face_offset.size() - 1));
  }
  write_vec3s(polyhedra.get(), "vertices", vertices, "m", file);
  const std::array<hsize_t, 1> dims_vo{vertex_offset.size()}, dims_fv{face_vertices.size()},
      dims_fo{face_offset.size()}, dims_pfo{polyhedron_face_offset.size()};
  write_integers(hdf5::write_int64s, polyhedra.get(), "vertex_offset", vertex_offset, dims_vo, file);
  write_integers(hdf5::write_int32s, polyhedra.get(), "face_vertices", face_vertices, dims_fv, file);
  write_integers(hdf5::write_int64s, polyhedra.get(), "face_offset", face_offset, dims_fo, file);
  write_integers(hdf5::write_int64s, polyhedra.get(), "polyhedron_face_offset", polyhedron_face_offset, dims_pfo, file);
  write_vec3s(polyhedra.get(), "face_normal", face_normals, "1", file);
}

/// /model/planes (the normals) and /model/boxes (the half extents): the walls' shape tables.
void write_walls(hid_t g, const Model& model, const fs::path& file) {
  {
    Handle planes = hdf5::create_group(g, "planes", file);
    std::vector<Vec3> normals;
    for (const Plane& plane : model.planes) normals.push_back(plane.normal);
    write_vec3s(planes.get(), "normal", normals, "1", file);
  }
  Handle boxes = hdf5::create_group(g, "boxes", file);
  std::vector<Vec3> half_extents;
  for (const Box& box : model.boxes) half_extents.push_back(box.half_extents);
  write_vec3s(boxes.get(), "half_extents", half_extents, "m", file);
}

/// /model/materials: names and densities.
void write_materials(hid_t g, const Model& model, const fs::path& file) {
  Handle materials = hdf5::create_group(g, "materials", file);
  std::vector<std::string> names;
  std::vector<double> density;
  for (const Material& m : model.materials) {
    names.push_back(m.name);
    density.push_back(m.density);
  }
  hdf5::write_strings(materials.get(), "name", names, file);
  write_column(materials.get(), "density", density, "kg/m^3", file);
}

/// /model/contact_laws: one (M, M) dataset per parameter of the material pairs' laws: friction,
/// restitution, then optional_contact_law_fields.
void write_contact_laws(hid_t g, const Model& model, const fs::path& file) {
  Handle laws = hdf5::create_group(g, "contact_laws", file);
  const auto m = static_cast<std::size_t>(model.contact_laws.material_count);
  std::vector<double> friction(m * m), restitution(m * m);
  for (std::size_t a = 0; a < m; ++a) {
    for (std::size_t b = 0; b < m; ++b) {
      const ContactLaw& law = model.contact_laws.get(static_cast<int>(a), static_cast<int>(b));
      friction[a * m + b] = law.friction_coefficient;
      restitution[a * m + b] = law.normal_restitution;
    }
  }
  const std::array<hsize_t, 2> dims{m, m};
  hdf5::write_doubles(laws.get(), "friction", friction, dims, file, storage);
  units(laws.get(), "friction", "1", file);
  hdf5::write_doubles(laws.get(), "restitution", restitution, dims, file, storage);
  units(laws.get(), "restitution", "1", file);
  for (const ContactLawField& field : optional_contact_law_fields) {
    std::vector<double> values(m * m);
    for (std::size_t i = 0; i < m * m; ++i) values[i] = model.contact_laws.laws[i].*field.member;
    hdf5::write_doubles(laws.get(), field.name, values, dims, file, storage);
    units(laws.get(), field.name, field.units, file);
  }
}

}  // namespace

void units(hid_t parent, const std::string& name, std::string_view value, const fs::path& file) {
  hdf5::write_attribute_on(parent, name, "units", value, file);
}

void write_run_parameter(hid_t run_group, const RunParameter& parameter, const fs::path& path) {
  if (parameter.name.empty() || parameter.name.find_first_of("/.") != std::string::npos) {
    throw std::invalid_argument(path.string() + ": bad run parameter name '" + parameter.name + "'");
  }
  if (H5Lexists(run_group, parameter.name.c_str(), H5P_DEFAULT) > 0) {
    hdf5::check(H5Ldelete(run_group, parameter.name.c_str(), H5P_DEFAULT), path,
                "cannot replace /run/" + parameter.name);
  }
  const std::array<hsize_t, 0> scalar{};
  hdf5::write_doubles(run_group, parameter.name, std::span<const double>(&parameter.value, 1), scalar, path);
  units(run_group, parameter.name, parameter.units, path);
  hdf5::write_attribute_on(run_group, parameter.name, "source", parameter.automatic ? "auto" : "scene", path);
}

void write_model(hid_t file_id, const Model& model, const fs::path& file) {
  Handle group = hdf5::create_group(file_id, "model", file);
  const hid_t g = group.get();
  write_bodies(g, model, file);
  write_polyhedra(g, model, file);
  write_walls(g, model, file);
  write_materials(g, model, file);
  write_contact_laws(g, model, file);
}

void write_state(hid_t group, const State& state, const fs::path& file) {
  const std::size_t n = state.body_count();
  write_vec3s(group, "position", state.position, "m", file);
  std::vector<double> orientation;
  orientation.reserve(4 * n);
  for (const Quat& q : state.orientation) orientation.insert(orientation.end(), {q.w(), q.x(), q.y(), q.z()});
  const std::array<hsize_t, 2> dims_q{state.orientation.size(), 4};
  hdf5::write_doubles(group, "orientation", orientation, dims_q, file, storage);
  units(group, "orientation", "1", file);
  write_vec3s(group, "velocity", state.velocity, "m/s", file);
  write_vec3s(group, "angular_velocity", state.angular_velocity, "rad/s", file);
}

void write_contacts(hid_t group, const ContactList& contacts, bool angular_impulses, const fs::path& file) {
  // Field by field, so that one field's copy (at most 24 bytes a contact) exists at a time: all
  // nine at once were ~140 bytes a contact beside the run's own arrays, the run's peak memory at
  // the last snapshot of a 1e5-sphere run.
  const std::size_t c = contacts.size();
  const std::array<hsize_t, 1> dims_c{c};
  const std::array<hsize_t, 2> dims_c3{c, 3};
  const auto write_ints = [&](const char* field_name, auto value) {
    std::vector<std::int32_t> column(c);
    for (std::size_t k = 0; k < c; ++k) column[k] = static_cast<std::int32_t>(value(contacts[k]));
    write_integers(hdf5::write_int32s, group, field_name, column, dims_c, file);
  };
  const auto write_vectors = [&](const char* field_name, std::string_view unit, auto value) {
    std::vector<double> flat;
    flat.reserve(3 * c);
    for (const Contact& contact : contacts) {
      const Vec3 v = value(contact);
      flat.insert(flat.end(), {v.x(), v.y(), v.z()});
    }
    hdf5::write_doubles(group, field_name, flat, dims_c3, file, storage);
    units(group, field_name, unit, file);
  };
  write_ints("contact_body_a", [](const Contact& x) { return x.id.body_a; });
  write_ints("contact_body_b", [](const Contact& x) { return x.id.body_b; });
  write_vectors("contact_point", "m", [](const Contact& x) -> Vec3 { return x.point; });
  write_vectors("contact_normal", "1", [](const Contact& x) -> Vec3 { return x.frame.col(0); });
  write_vectors("contact_tangent_t", "1", [](const Contact& x) -> Vec3 { return x.frame.col(1); });
  write_vectors("contact_tangent_s", "1", [](const Contact& x) -> Vec3 { return x.frame.col(2); });
  write_vectors("contact_impulse", "N s", [](const Contact& x) -> Vec3 { return x.impulse; });
  if (angular_impulses) {
    write_vectors("contact_angular_impulse", "N m s", [](const Contact& x) -> Vec3 { return x.angular_impulse; });
  }
  {
    std::vector<double> gap(c);
    for (std::size_t k = 0; k < c; ++k) gap[k] = contacts[k].gap;
    write_column(group, "contact_gap", gap, "m", file);
  }
  std::vector<std::int8_t> status(c);
  for (std::size_t k = 0; k < c; ++k) status[k] = static_cast<std::int8_t>(contacts[k].status);
  write_integers(hdf5::write_int8s, group, "contact_status", status, dims_c, file);
}

bool laws_resist_rotation(hid_t model, const fs::path& file) {
  Handle laws = hdf5::open_group(model, "contact_laws", file);
  for (const char* name : {"rolling_friction", "twisting_friction"}) {
    if (!hdf5::exists(laws.get(), name)) continue;
    const hdf5::Array<double> values = hdf5::read_doubles(laws.get(), name, file);
    if (std::any_of(values.values.begin(), values.values.end(), [](double v) { return v > 0.0; })) return true;
  }
  return false;
}

}  // namespace rubble::run_file_detail
