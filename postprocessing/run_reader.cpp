#include "postprocessing/run_reader.hpp"

#include <algorithm>
#include <cstdio>
#include <set>
#include <stdexcept>

#include "core/hdf5_io.hpp"
#include "postprocessing/run_file.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;
using hdf5::Handle;

[[noreturn]] void bad(const fs::path& file, const std::string& message) {
  throw std::runtime_error(file.string() + ": " + message);
}

/// Checks that a dataset has `rows` rows of `columns` values (columns 0: a 1-D dataset).
template <typename T>
void expect_shape(const hdf5::Array<T>& array, std::size_t rows, std::size_t columns, const std::string& name,
                  const fs::path& file) {
  const bool ok = columns == 0 ? array.dims.size() == 1 && array.dims[0] == rows
                               : array.dims.size() == 2 && array.dims[0] == rows && array.dims[1] == columns;
  if (!ok) {
    bad(file, "dataset '" + name + "' has the wrong shape (expected " + std::to_string(rows) +
                  (columns ? " x " + std::to_string(columns) : std::string()) + ")");
  }
}

std::vector<Vec3> read_vec3s(hid_t parent, const std::string& name, std::size_t rows, const fs::path& file) {
  const hdf5::Array<double> array = hdf5::read_doubles(parent, name, file);
  expect_shape(array, rows, 3, name, file);
  std::vector<Vec3> vectors(rows);
  for (std::size_t i = 0; i < rows; ++i)
    vectors[i] = Vec3(array.values[3 * i], array.values[3 * i + 1], array.values[3 * i + 2]);
  return vectors;
}

/// Reads a 3-column dataset whose row count is whatever the file says.
std::vector<Vec3> read_vec3s_any(hid_t parent, const std::string& name, const fs::path& file) {
  const hdf5::Array<double> array = hdf5::read_doubles(parent, name, file);
  return read_vec3s(parent, name, array.dims.empty() ? 0 : static_cast<std::size_t>(array.dims[0]), file);
}

std::vector<double> read_column(hid_t parent, const std::string& name, std::size_t rows, const fs::path& file) {
  hdf5::Array<double> array = hdf5::read_doubles(parent, name, file);
  expect_shape(array, rows, 0, name, file);
  return std::move(array.values);
}

std::vector<std::int64_t> read_int_column(hid_t parent, const std::string& name, std::size_t rows,
                                          const fs::path& file) {
  hdf5::Array<std::int64_t> array = hdf5::read_int64s(parent, name, file);
  expect_shape(array, rows, 0, name, file);
  return std::move(array.values);
}

std::vector<std::int64_t> read_int_column_any(hid_t parent, const std::string& name, const fs::path& file) {
  hdf5::Array<std::int64_t> array = hdf5::read_int64s(parent, name, file);
  if (array.dims.size() != 1) bad(file, "dataset '" + name + "' is not 1-D");
  return std::move(array.values);
}

/// The per-body datasets of /model, read before the shape tables that their indices point into.
struct BodyColumns {
  std::vector<std::int64_t> kind_codes, shape_index, material;
  std::vector<double> radius;
};

/// Reads the per-body datasets: mass, volume, bounding radius and principal moments into `model`,
/// the shape kinds and indices, materials and sphere radii into the returned columns (checked in
/// add_bodies once the tables are read).
BodyColumns read_body_columns(hid_t g, Model& model, const fs::path& file) {
  BodyColumns columns;
  columns.kind_codes = read_int_column_any(g, "body_shape_kind", file);
  const std::size_t n = columns.kind_codes.size();
  columns.shape_index = read_int_column(g, "body_shape_index", n, file);
  columns.material = read_int_column(g, "material", n, file);
  model.mass = read_column(g, "mass", n, file);
  model.volume = read_column(g, "volume", n, file);
  model.bounding_radius = read_column(g, "bounding_radius", n, file);
  columns.radius = read_column(g, "radius", n, file);
  model.principal_inertia = read_vec3s(g, "principal_inertia", n, file);
  return columns;
}

/// /model/materials and /model/contact_laws (the parameters of optional_contact_law_fields are 0
/// in a file written before they were stored).
void read_materials_and_laws(hid_t g, Model& model, const fs::path& file) {
  Handle materials = hdf5::open_group(g, "materials", file);
  const std::vector<std::string> names = hdf5::read_strings(materials.get(), "name", file);
  const std::vector<double> density = read_column(materials.get(), "density", names.size(), file);
  for (std::size_t m = 0; m < names.size(); ++m) model.materials.push_back({names[m], density[m]});
  Handle laws = hdf5::open_group(g, "contact_laws", file);
  const std::size_t count = names.size();
  const hdf5::Array<double> friction = hdf5::read_doubles(laws.get(), "friction", file);
  const hdf5::Array<double> restitution = hdf5::read_doubles(laws.get(), "restitution", file);
  expect_shape(friction, count, count, "contact_laws/friction", file);
  expect_shape(restitution, count, count, "contact_laws/restitution", file);
  model.contact_laws.reset(static_cast<int>(count), ContactLaw{});
  for (std::size_t k = 0; k < count * count; ++k) {
    model.contact_laws.laws[k] = ContactLaw{friction.values[k], restitution.values[k]};
  }
  for (const ContactLawField& field : optional_contact_law_fields) {
    if (!hdf5::exists(laws.get(), field.name)) continue;  // a file written before they were stored
    const hdf5::Array<double> values = hdf5::read_doubles(laws.get(), field.name, file);
    expect_shape(values, count, count, std::string("contact_laws/") + field.name, file);
    for (std::size_t k = 0; k < count * count; ++k) model.contact_laws.laws[k].*field.member = values.values[k];
  }
}

/// The flat arrays of /model/polyhedra (layout: docs/output-format.md).
struct PolyhedronTables {
  std::vector<Vec3> vertices;
  std::vector<std::int64_t> vertex_offset, face_vertices, face_offset, polyhedron_face_offset;
  std::vector<Vec3> face_normal;
};

bool in_range(std::int64_t value, std::size_t end) { return value >= 0 && static_cast<std::size_t>(value) <= end; }

/// Polyhedron `s` of the tables, its offsets and indices checked, its edges rebuilt from its faces.
ConvexPolyhedron polyhedron_from_tables(const PolyhedronTables& t, std::size_t s, const fs::path& file) {
  ConvexPolyhedron shape;
  const std::int64_t v0 = t.vertex_offset[s], v1 = t.vertex_offset[s + 1];
  const std::int64_t f0 = t.polyhedron_face_offset[s], f1 = t.polyhedron_face_offset[s + 1];
  if (!in_range(v0, t.vertices.size()) || !in_range(v1, t.vertices.size()) || v1 < v0 ||
      !in_range(f0, t.face_normal.size()) || !in_range(f1, t.face_normal.size()) || f1 < f0) {
    bad(file, "polyhedra: offsets of polyhedron " + std::to_string(s) + " out of range");
  }
  shape.vertices.assign(t.vertices.begin() + v0, t.vertices.begin() + v1);
  std::set<std::pair<int, int>> edges;
  for (std::int64_t f = f0; f < f1; ++f) {
    const std::int64_t k0 = t.face_offset[static_cast<std::size_t>(f)],
                       k1 = t.face_offset[static_cast<std::size_t>(f) + 1];
    if (!in_range(k0, t.face_vertices.size()) || !in_range(k1, t.face_vertices.size()) || k1 < k0 + 3) {
      bad(file, "polyhedra: face " + std::to_string(f) + " has bad offsets or fewer than 3 vertices");
    }
    std::vector<int> face;
    for (std::int64_t k = k0; k < k1; ++k) {
      const std::int64_t v = t.face_vertices[static_cast<std::size_t>(k)];
      if (v < 0 || v >= v1 - v0) bad(file, "polyhedra: face " + std::to_string(f) + " has a vertex index out of range");
      face.push_back(static_cast<int>(v));
    }
    for (std::size_t k = 0; k < face.size(); ++k) {
      const int a = face[k], b = face[(k + 1) % face.size()];
      edges.insert({std::min(a, b), std::max(a, b)});
    }
    shape.faces.push_back(std::move(face));
    shape.face_normals.push_back(t.face_normal[static_cast<std::size_t>(f)]);
  }
  shape.edges.assign(edges.begin(), edges.end());
  return shape;
}

/// /model/polyhedra into model.polyhedra.
void read_polyhedra(hid_t g, Model& model, const fs::path& file) {
  Handle polyhedra = hdf5::open_group(g, "polyhedra", file);
  const hid_t p = polyhedra.get();
  PolyhedronTables t;
  t.vertices = read_vec3s_any(p, "vertices", file);
  t.vertex_offset = read_int_column_any(p, "vertex_offset", file);
  t.face_vertices = read_int_column_any(p, "face_vertices", file);
  t.face_offset = read_int_column_any(p, "face_offset", file);
  t.polyhedron_face_offset = read_int_column_any(p, "polyhedron_face_offset", file);
  t.face_normal = read_vec3s(p, "face_normal", t.face_offset.empty() ? 0 : t.face_offset.size() - 1, file);
  const std::size_t count = t.vertex_offset.empty() ? 0 : t.vertex_offset.size() - 1;
  if (t.polyhedron_face_offset.size() != count + 1)
    bad(file, "polyhedra: vertex_offset and polyhedron_face_offset differ in length");
  for (std::size_t s = 0; s < count; ++s) model.polyhedra.push_back(polyhedron_from_tables(t, s, file));
}

/// /model/planes and /model/boxes: the walls' shape tables.
void read_walls(hid_t g, Model& model, const fs::path& file) {
  Handle planes = hdf5::open_group(g, "planes", file);
  for (const Vec3& normal : read_vec3s_any(planes.get(), "normal", file)) model.planes.push_back(Plane{normal});
  Handle boxes = hdf5::open_group(g, "boxes", file);
  for (const Vec3& half : read_vec3s_any(boxes.get(), "half_extents", file)) model.boxes.push_back(Box{half});
}

/// Per body, its shape kind and index and its material checked against the tables; spheres get
/// their table back from the per-body radius; inverse mass and inertia follow from the columns.
void add_bodies(const BodyColumns& columns, Model& model, const fs::path& file) {
  for (std::size_t i = 0; i < columns.kind_codes.size(); ++i) {
    const std::int64_t code = columns.kind_codes[i];
    if (code < 0 || code > static_cast<std::int64_t>(ShapeKind::box)) {
      bad(file, "model: body " + std::to_string(i) + " has an unknown shape kind " + std::to_string(code));
    }
    const auto kind = static_cast<ShapeKind>(code);
    const std::int64_t index = columns.shape_index[i];
    const std::size_t table_size = kind == ShapeKind::sphere       ? static_cast<std::size_t>(-1)
                                   : kind == ShapeKind::polyhedron ? model.polyhedra.size()
                                   : kind == ShapeKind::plane      ? model.planes.size()
                                                                   : model.boxes.size();
    if (index < 0 || static_cast<std::size_t>(index) >= table_size) {
      bad(file, "model: body " + std::to_string(i) + " has a shape index out of range");
    }
    const std::int64_t material = columns.material[i];
    if (material < 0 || static_cast<std::size_t>(material) >= model.materials.size()) {
      bad(file, "model: body " + std::to_string(i) + " has a material out of range");
    }
    if (kind == ShapeKind::sphere) {
      if (model.spheres.size() <= static_cast<std::size_t>(index))
        model.spheres.resize(static_cast<std::size_t>(index) + 1);
      model.spheres[static_cast<std::size_t>(index)].radius = columns.radius[i];
    }
    model.shape_kind.push_back(kind);
    model.shape_index.push_back(static_cast<int>(index));
    model.material.push_back(static_cast<int>(material));
    model.inverse_mass.push_back(model.mass[i] > 0.0 ? 1.0 / model.mass[i] : 0.0);
    model.inverse_inertia.push_back(model.mass[i] > 0.0 ? Vec3(model.principal_inertia[i].cwiseInverse())
                                                        : Vec3::Zero());
  }
}

Model read_model(hid_t root, const fs::path& file) {
  Handle group = hdf5::open_group(root, "model", file);
  const hid_t g = group.get();
  Model model;
  const BodyColumns columns = read_body_columns(g, model, file);
  read_materials_and_laws(g, model, file);
  read_polyhedra(g, model, file);
  read_walls(g, model, file);
  add_bodies(columns, model, file);
  return model;
}

}  // namespace

struct RunReader::Impl {
  fs::path path;
  Handle file;
  Model model;
  std::string scene_text;
  std::vector<std::string> snapshot_names;
  std::string status = "unknown";
  bool live = false;
  mutable double time_step = -1.0;  // cached; -1: not computed yet
};

namespace {

/// Opens a run file read-only. HDF5 1.10 refuses a file that another process holds open for
/// writing ("unable to lock file"): a running `rubble run`. Such a file is opened again without
/// the lock: the writer keeps the file's metadata in memory between its flushes
/// (RunFile::hold_metadata_until_flush), so the file on disk is the run as of its last flush.
Handle open_run_file(const fs::path& path, bool& live) {
  live = false;
  if (!fs::exists(path)) throw std::runtime_error(path.string() + ": no such file");
  hid_t id = -1;
  H5E_BEGIN_TRY { id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT); }
  H5E_END_TRY;
  if (id >= 0) return Handle(id, H5Fclose);
  const std::string reason = hdf5::last_error_message();
  if (reason.find("lock") == std::string::npos) return hdf5::own(id, H5Fclose, path, "cannot open as an HDF5 file");
  Handle access = hdf5::own(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, path, "file access properties");
  hdf5::check(H5Pset_file_locking(access.get(), false, true), path, "file access properties");
  H5E_BEGIN_TRY { id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, access.get()); }
  H5E_END_TRY;
  if (id < 0) {
    throw std::runtime_error(path.string() + ": open for writing by a running `rubble run` (HDF5 file lock: " + reason +
                             ") and not readable without the lock (" + hdf5::last_error_message() +
                             "); wait for the run to end or stop it (Ctrl-C writes its state and a checkpoint)");
  }
  live = true;
  return Handle(id, H5Fclose);
}

}  // namespace

RunReader::RunReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RunReader::RunReader(RunReader&&) noexcept = default;
RunReader& RunReader::operator=(RunReader&&) noexcept = default;
RunReader::~RunReader() = default;

RunReader RunReader::open(const fs::path& path) {
  const hdf5::QuietErrors quiet;
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->file = open_run_file(path, impl->live);
  const hid_t root = impl->file.get();
  if (H5Aexists(root, "format") <= 0 || hdf5::read_string_attribute(root, "format", path) != run_file_format) {
    bad(path, "not a rubble run file (root attribute format != \"rubble-run\")");
  }
  const double version = hdf5::read_double_attribute(root, "format_version", path);
  if (version > run_file_format_version) {
    bad(path, "run file format version " + std::to_string(static_cast<int>(version)) +
                  " is newer than this rubble reads (" + std::to_string(run_file_format_version) + ")");
  }
  if (version >= 2) {
    Handle run = hdf5::open_group(root, "run", path);
    impl->status = hdf5::read_string_attribute(run.get(), "status", path);
    if (hdf5::exists(run.get(), "time_step")) {
      const hdf5::Array<double> h = hdf5::read_doubles(run.get(), "time_step", path);
      if (h.values.size() == 1 && h.values[0] > 0.0) impl->time_step = h.values[0];
    }
  }
  impl->scene_text = hdf5::read_string(root, "scene", path);
  impl->model = read_model(root, path);
  Handle snapshots = hdf5::open_group(root, "snapshots", path);
  impl->snapshot_names = hdf5::link_names(snapshots.get(), path);
  std::sort(impl->snapshot_names.begin(), impl->snapshot_names.end());  // NNNNNN: by name is by time
  return RunReader(std::move(impl));
}

const fs::path& RunReader::path() const { return impl_->path; }
const Model& RunReader::model() const { return impl_->model; }
const std::string& RunReader::scene_text() const { return impl_->scene_text; }
std::size_t RunReader::snapshot_count() const { return impl_->snapshot_names.size(); }
const std::string& RunReader::status() const { return impl_->status; }
bool RunReader::live() const { return impl_->live; }

RunSnapshot RunReader::read_snapshot(std::size_t index) const {
  const Impl& r = *impl_;
  if (index >= r.snapshot_names.size()) {
    bad(r.path,
        "snapshot " + std::to_string(index) + " requested, the file has " + std::to_string(r.snapshot_names.size()));
  }
  const hdf5::QuietErrors quiet;
  const std::string name = "snapshots/" + r.snapshot_names[index];
  Handle group = hdf5::open_group(r.file.get(), name, r.path);
  const hid_t g = group.get();
  const fs::path where = r.path.string() + ":/" + name;
  RunSnapshot snapshot;
  State& state = snapshot.state;
  const std::size_t n = r.model.body_count();
  state.time = hdf5::read_double_attribute(g, "time", where);
  state.step = static_cast<std::int64_t>(hdf5::read_double_attribute(g, "step", where));
  snapshot.bodies_in_play = n;
  if (H5Aexists(g, "bodies_in_play") > 0) {
    const double in_play = hdf5::read_double_attribute(g, "bodies_in_play", where);
    if (!(in_play >= 0.0 && in_play <= static_cast<double>(n))) {
      bad(where, "@bodies_in_play = " + std::to_string(in_play) + ", expected 0 to " + std::to_string(n));
    }
    snapshot.bodies_in_play = static_cast<std::size_t>(in_play);
  }
  state.position = read_vec3s(g, "position", n, where);
  const hdf5::Array<double> orientation = hdf5::read_doubles(g, "orientation", where);
  expect_shape(orientation, n, 4, "orientation", where);
  for (std::size_t i = 0; i < n; ++i) {
    const double* q = &orientation.values[4 * i];
    state.orientation.emplace_back(q[0], q[1], q[2], q[3]);  // Eigen's constructor is (w, x, y, z)
  }
  state.velocity = read_vec3s(g, "velocity", n, where);
  state.angular_velocity = read_vec3s(g, "angular_velocity", n, where);

  const std::vector<std::int64_t> body_a = read_int_column_any(g, "contact_body_a", where);
  const std::size_t c = body_a.size();
  const std::vector<std::int64_t> body_b = read_int_column(g, "contact_body_b", c, where);
  const std::vector<Vec3> point = read_vec3s(g, "contact_point", c, where);
  const std::vector<Vec3> normal = read_vec3s(g, "contact_normal", c, where);
  const std::vector<Vec3> tangent_t = read_vec3s(g, "contact_tangent_t", c, where);
  const std::vector<Vec3> tangent_s = read_vec3s(g, "contact_tangent_s", c, where);
  const std::vector<Vec3> impulse = read_vec3s(g, "contact_impulse", c, where);
  const std::vector<double> gap = read_column(g, "contact_gap", c, where);
  const std::vector<std::int64_t> status = read_int_column(g, "contact_status", c, where);
  // Only in runs whose laws resist rotation (docs/output-format.md): zero otherwise.
  const std::vector<Vec3> angular_impulse = hdf5::exists(g, "contact_angular_impulse")
                                                ? read_vec3s(g, "contact_angular_impulse", c, where)
                                                : std::vector<Vec3>(c, Vec3::Zero());
  snapshot.contacts.resize(c);
  for (std::size_t k = 0; k < c; ++k) {
    if (body_a[k] < 0 || body_b[k] < 0 || static_cast<std::size_t>(body_a[k]) >= n ||
        static_cast<std::size_t>(body_b[k]) >= n) {
      bad(where, "contact " + std::to_string(k) + " names a body out of range");
    }
    if (status[k] < 0 || status[k] > static_cast<std::int64_t>(ContactStatus::sliding)) {
      bad(where, "contact " + std::to_string(k) + " has an unknown status");
    }
    Contact& contact = snapshot.contacts[k];
    contact.id.body_a = static_cast<std::uint32_t>(body_a[k]);
    contact.id.body_b = static_cast<std::uint32_t>(body_b[k]);
    contact.point = point[k];
    contact.frame.col(0) = normal[k];
    contact.frame.col(1) = tangent_t[k];
    contact.frame.col(2) = tangent_s[k];
    contact.gap = gap[k];
    contact.impulse = impulse[k];
    contact.angular_impulse = angular_impulse[k];
    contact.status = static_cast<ContactStatus>(status[k]);
  }
  return snapshot;
}

RunSeries RunReader::read_series() const {
  const Impl& r = *impl_;
  const hdf5::QuietErrors quiet;
  Handle group = hdf5::open_group(r.file.get(), "series", r.path);
  const hid_t g = group.get();
  RunSeries series;
  series.step = read_int_column_any(g, "step", r.path);
  const std::size_t rows = series.step.size();
  series.time = read_column(g, "time", rows, r.path);
  series.kinetic_energy = read_column(g, "kinetic_energy", rows, r.path);
  series.contacts = read_int_column(g, "contacts", rows, r.path);
  series.active_contacts = read_int_column(g, "active_contacts", rows, r.path);
  series.iterations = read_int_column(g, "iterations", rows, r.path);
  series.residual = read_column(g, "residual", rows, r.path);
  series.wall_seconds = read_column(g, "wall_seconds", rows, r.path);
  const std::vector<std::string> present = hdf5::link_names(g, r.path);
  for (const char* name : {"potential_energy", "total_energy", "linear_momentum_x", "linear_momentum_y",
                           "linear_momentum_z", "angular_momentum_x", "angular_momentum_y", "angular_momentum_z"}) {
    if (std::find(present.begin(), present.end(), name) == present.end()) continue;
    series.monitor_names.emplace_back(name);
    series.monitor.push_back(read_column(g, name, rows, r.path));
  }
  Handle stages = hdf5::open_group(g, "stage_seconds", r.path);
  series.stage_names = hdf5::link_names(stages.get(), r.path);
  for (const std::string& name : series.stage_names)
    series.stage_seconds.push_back(read_column(stages.get(), name, rows, r.path));
  return series;
}

double RunReader::time_step() const {
  if (impl_->time_step >= 0.0) return impl_->time_step;
  const RunSeries series = read_series();
  double h = 0.0;
  const std::size_t rows = series.step.size();
  if (rows >= 2 && series.step[rows - 1] > series.step[0]) {
    h = (series.time[rows - 1] - series.time[0]) / static_cast<double>(series.step[rows - 1] - series.step[0]);
  } else if (rows == 1 && series.step[0] > 0) {
    h = series.time[0] / static_cast<double>(series.step[0]);
  }
  impl_->time_step = h;
  return h;
}

}  // namespace rubble
