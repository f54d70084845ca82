#include "postprocessing/run_file.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <optional>
#include <set>
#include <stdexcept>

#include "core/hdf5_io.hpp"
#include "postprocessing/run_file_datasets.hpp"

#ifndef RUBBLE_VERSION
#define RUBBLE_VERSION "unknown"
#endif

namespace rubble {
namespace {

using hdf5::Handle;
using run_file_detail::units;
namespace fs = std::filesystem;

/// The columns that grow row by row (/series, /snapshot_time, /snapshot_step) keep the checksum but
/// are not compressed: a compressed chunk rewritten with more rows changes size and moves in the
/// file, so a run killed between two flushes (SIGKILL, power loss) left an index pointing at space
/// since reused, read back as a Fletcher-32 error; uncompressed chunks are rewritten in place and a
/// killed run's file stays readable up to its last flush (tests/apps/one_run_per_folder.sh). They
/// are a few doubles a step, so compression would save little.
constexpr hdf5::Storage appended_storage{true, 0, false};

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> text{};
  std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text.data();
}

/// A series column: its name, HDF5 type and units.
struct ColumnSpec {
  const char* name;
  hid_t type;
  const char* units;
};

/// The series columns of SeriesRow's first fields, in this order (types are HDF5's native ones,
/// which are macros, not constants: the table is built when used).
std::array<ColumnSpec, 8> basic_columns() {
  return {{{"step", H5T_NATIVE_INT64, "1"},
           {"time", H5T_NATIVE_DOUBLE, "s"},
           {"kinetic_energy", H5T_NATIVE_DOUBLE, "J"},
           {"contacts", H5T_NATIVE_INT64, "1"},
           {"active_contacts", H5T_NATIVE_INT64, "1"},
           {"iterations", H5T_NATIVE_INT, "1"},
           {"residual", H5T_NATIVE_DOUBLE, "1"},
           {"wall_seconds", H5T_NATIVE_DOUBLE, "s"}}};
}

/// The conservation monitor's series columns (double, one value a step), in this order.
constexpr std::array<const char*, 8> conservation_columns{
    "potential_energy",  "total_energy",       "linear_momentum_x",  "linear_momentum_y",
    "linear_momentum_z", "angular_momentum_x", "angular_momentum_y", "angular_momentum_z"};
/// Their units.
constexpr std::array<const char*, 8> conservation_units{"J",      "J",        "kg m/s",   "kg m/s",
                                                        "kg m/s", "kg m^2/s", "kg m^2/s", "kg m^2/s"};

/// Rows per chunk of the series and of the snapshot index.
constexpr hsize_t series_chunk_rows = 1024;

}  // namespace

std::string_view run_status_name(RunStatus status) {
  switch (status) {
    case RunStatus::running:
      return "running";
    case RunStatus::at_rest:
      return "at_rest";
    case RunStatus::end_time:
      return "end_time";
    case RunStatus::interrupted:
      return "interrupted";
    case RunStatus::numerical_failure:
      return "numerical_failure";
    case RunStatus::closed:
      return "closed";
  }
  return "running";
}

/// The open file, its series columns and the rows not yet written.

struct RunFile::Impl {
  fs::path path;
  Handle file;
  Handle series_group;
  Handle stage_group;
  Handle snapshots_group;
  Handle run_group;
  std::vector<std::string> stage_names;
  // One column per series dataset, in the order of SeriesRow's fields.
  std::vector<hdf5::ExtendableColumn> columns;                 // step .. wall_seconds
  std::vector<hdf5::ExtendableColumn> stage_columns;           // one per stage
  std::optional<hdf5::ExtendableColumn> snapshot_time_column;  // /snapshot_time
  std::optional<hdf5::ExtendableColumn> snapshot_step_column;  // /snapshot_step
  std::vector<double> snapshot_times;                          // s, of every snapshot in the file
  std::int64_t last_snapshot_step = -1;
  // Buffered rows, column by column.
  std::vector<std::int64_t> step, contacts, active_contacts;
  std::vector<int> iterations;
  std::vector<double> time, kinetic_energy, residual, wall_seconds;
  // The conservation monitor, after wall_seconds: potential_energy, total_energy, linear_momentum_x,
  // _y, _z, angular_momentum_x, _y, _z (conservation_columns).
  std::vector<std::vector<double>> conservation = std::vector<std::vector<double>>(conservation_columns.size());
  std::vector<std::vector<double>> stage_seconds;
  std::int64_t rows = 0;
  std::int64_t snapshots = 0;
  std::size_t body_count = 0;  // of the model: every snapshot has this many bodies
  // Whether a contact law resists rolling or twisting: only then do snapshots carry the contacts'
  // angular impulses (contact_angular_impulse), so a plain run's file stays as it was.
  bool angular_impulses = false;
  // A write or flush failed (disk full, I/O error): the file is not flushed again on close, and
  // later writes are refused, so that HDF5 is not asked to retry what cannot succeed.
  bool failed = false;

  /// Runs one write; a failure marks the file failed and is passed on.
  template <typename Write>
  void guarded(Write&& write) {
    if (failed) throw std::runtime_error(path.string() + ": an earlier write to the run file failed");
    try {
      write();
    } catch (...) {
      failed = true;
      throw;
    }
  }

  /// Closes every object, children before the file (HDF5 keeps a file open while any of its
  /// objects is), with HDF5's error printing off: after a failed write the closes fail too.
  void close() noexcept {
    const hdf5::QuietErrors quiet;
    columns.clear();
    stage_columns.clear();
    snapshot_time_column.reset();
    snapshot_step_column.reset();
    run_group.reset();
    stage_group.reset();
    series_group.reset();
    snapshots_group.reset();
    file.reset();
  }

  void write_buffered_rows() {
    const std::size_t count = step.size();
    if (count == 0) return;
    columns[0].append(step.data(), count, path);
    columns[1].append(time.data(), count, path);
    columns[2].append(kinetic_energy.data(), count, path);
    columns[3].append(contacts.data(), count, path);
    columns[4].append(active_contacts.data(), count, path);
    columns[5].append(iterations.data(), count, path);
    columns[6].append(residual.data(), count, path);
    columns[7].append(wall_seconds.data(), count, path);
    for (std::size_t c = 0; c < conservation.size(); ++c) columns[8 + c].append(conservation[c].data(), count, path);
    for (auto& column : conservation) column.clear();
    for (std::size_t s = 0; s < stage_columns.size(); ++s)
      stage_columns[s].append(stage_seconds[s].data(), count, path);
    for (auto* column : {&step, &contacts, &active_contacts}) column->clear();
    for (auto* column : {&time, &kinetic_energy, &residual, &wall_seconds}) column->clear();
    iterations.clear();
    for (auto& column : stage_seconds) column.clear();
  }
};

RunFile::RunFile(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RunFile::RunFile(RunFile&&) noexcept = default;

RunFile& RunFile::operator=(RunFile&& other) noexcept {
  if (this != &other) {
    RunFile closing(std::move(*this));  // flushed and closed at the end of this scope
    impl_ = std::move(other.impl_);
  }
  return *this;
}

RunFile::~RunFile() {
  if (!impl_) return;
  if (!impl_->failed) {
    try {
      flush();
    } catch (const std::exception& error) {
      // A destructor must not throw; the run loop calls flush() itself to see errors.
      std::fprintf(stderr, "rubble: run file not flushed on close: %s\n", error.what());
    }
  }
  impl_->close();
}

RunFile RunFile::create(const fs::path& path, const Model& model, std::string_view scene_text,
                        std::span<const std::string_view> stage_names, std::span<const RunParameter> parameters) {
  std::set<std::string_view> unique_names;
  for (std::string_view name : stage_names) {
    if (name.empty() || name.find_first_of("/.") != std::string_view::npos || !unique_names.insert(name).second) {
      throw std::invalid_argument(path.string() + ": bad stage name '" + std::string(name) +
                                  "' (expected unique, non-empty names without '/' or '.')");
    }
  }
  const hdf5::QuietErrors quiet;
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->body_count = model.body_count();
  impl->angular_impulses = model.contact_laws.any_resists_rotation();
  impl->file = hdf5::create_file(path, hdf5::ChunkIndex::small);
  const hid_t root = impl->file.get();

  hdf5::write_attribute(root, "format", run_file_format, path);
  hdf5::write_attribute(root, "format_version", static_cast<std::int64_t>(run_file_format_version), path);
  hdf5::write_attribute(root, "rubble_version", std::string_view(RUBBLE_VERSION), path);
  hdf5::write_attribute(root, "created", std::string_view(utc_now_iso8601()), path);
  hdf5::write_string(root, "scene", scene_text, path);
  run_file_detail::write_model(root, model, path);

  // How the run was set up, with its "auto" values resolved, and whether it has ended.
  impl->run_group = hdf5::create_group(root, "run", path);
  hdf5::write_attribute(impl->run_group.get(), "status", run_status_name(RunStatus::running), path);
  hdf5::write_attribute(impl->run_group.get(), "stop_reason", std::string_view(), path);
  for (const RunParameter& parameter : parameters)
    run_file_detail::write_run_parameter(impl->run_group.get(), parameter, path);

  impl->series_group = hdf5::create_group(root, "series", path);
  const hid_t series = impl->series_group.get();
  for (const ColumnSpec& column : basic_columns()) {
    impl->columns.emplace_back(series, column.name, column.type, series_chunk_rows, path, appended_storage);
    units(series, column.name, column.units, path);
  }
  for (std::size_t c = 0; c < conservation_columns.size(); ++c) {
    impl->columns.emplace_back(series, conservation_columns[c], H5T_NATIVE_DOUBLE, series_chunk_rows, path,
                               appended_storage);
    units(series, conservation_columns[c], conservation_units[c], path);
  }
  impl->stage_group = hdf5::create_group(series, "stage_seconds", path);
  for (std::string_view name : stage_names) {
    impl->stage_names.emplace_back(name);
    impl->stage_columns.emplace_back(impl->stage_group.get(), std::string(name), H5T_NATIVE_DOUBLE, series_chunk_rows,
                                     path, appended_storage);
    units(impl->stage_group.get(), std::string(name), "s", path);
  }
  hdf5::write_attribute(impl->stage_group.get(), "stage_order", std::span<const std::string>(impl->stage_names), path);
  impl->stage_seconds.resize(stage_names.size());
  impl->snapshots_group = hdf5::create_group(root, "snapshots", path);
  impl->snapshot_time_column.emplace(root, "snapshot_time", H5T_NATIVE_DOUBLE, series_chunk_rows, path,
                                     appended_storage);
  units(root, "snapshot_time", "s", path);
  impl->snapshot_step_column.emplace(root, "snapshot_step", H5T_NATIVE_INT64, series_chunk_rows, path,
                                     appended_storage);
  units(root, "snapshot_step", "1", path);
  hdf5::check(H5Fflush(root, H5F_SCOPE_LOCAL), path, "cannot flush");
  return RunFile(std::move(impl));
}

RunFile RunFile::reopen(const fs::path& path, std::int64_t last_step, std::span<const std::string_view> stage_names) {
  const hdf5::QuietErrors quiet;
  if (!fs::exists(path)) throw std::runtime_error(path.string() + ": no such run file");
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->file = hdf5::own(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, path,
                         "cannot open the run file for writing");
  const hid_t root = impl->file.get();
  if (H5Aexists(root, "format") <= 0 || hdf5::read_string_attribute(root, "format", path) != run_file_format) {
    throw std::runtime_error(path.string() + ": not a rubble run file (no /@format = rubble-run)");
  }
  if (hdf5::read_double_attribute(root, "format_version", path) != run_file_format_version) {
    throw std::runtime_error(path.string() + ": run file layout version differs from this rubble's");
  }
  Handle model = hdf5::open_group(root, "model", path);
  impl->body_count = static_cast<std::size_t>(hdf5::read_double_attribute(model.get(), "body_count", path));
  impl->angular_impulses = run_file_detail::laws_resist_rotation(model.get(), path);

  // Steps are appended in increasing order: keep the leading rows up to last_step.
  impl->series_group = hdf5::open_group(root, "series", path);
  const hid_t series = impl->series_group.get();
  const hdf5::Array<std::int64_t> steps = hdf5::read_int64s(series, "step", path);
  const auto keep = static_cast<hsize_t>(
      std::find_if(steps.values.begin(), steps.values.end(), [&](std::int64_t s) { return s > last_step; }) -
      steps.values.begin());
  for (const ColumnSpec& column : basic_columns()) {
    impl->columns.push_back(hdf5::ExtendableColumn::open_truncated(series, column.name, column.type, keep, path));
  }
  for (const char* name : conservation_columns) {
    impl->columns.push_back(hdf5::ExtendableColumn::open_truncated(series, name, H5T_NATIVE_DOUBLE, keep, path));
  }
  impl->stage_group = hdf5::open_group(series, "stage_seconds", path);
  for (std::string_view name : stage_names) {
    impl->stage_names.emplace_back(name);
    impl->stage_columns.push_back(hdf5::ExtendableColumn::open_truncated(impl->stage_group.get(), std::string(name),
                                                                         H5T_NATIVE_DOUBLE, keep, path));
  }
  impl->stage_seconds.resize(stage_names.size());
  impl->rows = static_cast<std::int64_t>(keep);

  // Snapshots are numbered in the order written, and steps grow with the number: drop the tail
  // written after last_step, and the state at an interruption (the run goes on from it).
  impl->snapshots_group = hdf5::open_group(root, "snapshots", path);
  const hid_t snapshots = impl->snapshots_group.get();
  for (const std::string& name : hdf5::link_names(snapshots, path)) {
    Handle group = hdf5::open_group(snapshots, name, path);
    const double step = hdf5::read_double_attribute(group.get(), "step", path);
    const double time = hdf5::read_double_attribute(group.get(), "time", path);
    const bool interrupted = hdf5::read_double_attribute(group.get(), "interrupted", path) != 0.0;
    group.reset();
    if (step > static_cast<double>(last_step) || interrupted) {
      hdf5::check(H5Ldelete(snapshots, name.c_str(), H5P_DEFAULT), path, "cannot remove snapshot " + name);
      continue;
    }
    std::array<char, 16> expected{};
    std::snprintf(expected.data(), expected.size(), "%06lld", static_cast<long long>(impl->snapshots));
    if (name != expected.data()) {
      throw std::runtime_error(path.string() + ": snapshot " + name + " out of sequence (expected " + expected.data() +
                               ")");
    }
    ++impl->snapshots;
    impl->snapshot_times.push_back(time);
    impl->last_snapshot_step = static_cast<std::int64_t>(step);
  }
  const auto kept = static_cast<hsize_t>(impl->snapshots);
  impl->snapshot_time_column.emplace(
      hdf5::ExtendableColumn::open_truncated(root, "snapshot_time", H5T_NATIVE_DOUBLE, kept, path));
  impl->snapshot_step_column.emplace(
      hdf5::ExtendableColumn::open_truncated(root, "snapshot_step", H5T_NATIVE_INT64, kept, path));
  if (impl->snapshot_time_column->size() != kept || impl->snapshot_step_column->size() != kept) {
    throw std::runtime_error(path.string() + ": /snapshot_time or /snapshot_step is shorter than the snapshots");
  }
  impl->run_group = hdf5::open_group(root, "run", path);
  hdf5::replace_attribute(impl->run_group.get(), "status", run_status_name(RunStatus::running), path);
  hdf5::replace_attribute(impl->run_group.get(), "stop_reason", std::string_view(), path);
  hdf5::check(H5Fflush(root, H5F_SCOPE_LOCAL), path, "cannot flush");
  return RunFile(std::move(impl));
}

void RunFile::hold_metadata_until_flush() {
  Impl& f = *impl_;
  const hdf5::QuietErrors quiet;
  H5AC_cache_config_t config{};
  config.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  hdf5::check(H5Fget_mdc_config(f.file.get(), &config), f.path, "cannot read the metadata cache settings");
  // HDF5 allows turning evictions off only with automatic resizing off (H5Pset_mdc_config).
  config.evictions_enabled = false;
  config.incr_mode = H5C_incr__off;
  config.flash_incr_mode = H5C_flash_incr__off;
  config.decr_mode = H5C_decr__off;
  hdf5::check(H5Fset_mdc_config(f.file.get(), &config), f.path, "cannot set the metadata cache settings");
}

void RunFile::append_series(const SeriesRow& row) {
  Impl& f = *impl_;
  if (row.stage_seconds.size() != f.stage_names.size()) {
    throw std::invalid_argument(f.path.string() + ": series row has " + std::to_string(row.stage_seconds.size()) +
                                " stage times, the file has " + std::to_string(f.stage_names.size()) + " stages");
  }
  f.step.push_back(row.step);
  f.time.push_back(row.time);
  f.kinetic_energy.push_back(row.kinetic_energy);
  f.contacts.push_back(row.contacts);
  f.active_contacts.push_back(row.active_contacts);
  f.iterations.push_back(row.iterations);
  f.residual.push_back(row.residual);
  f.wall_seconds.push_back(row.wall_seconds);
  const std::array<double, conservation_columns.size()> monitor{
      row.potential_energy,    row.total_energy,         row.linear_momentum.x(),  row.linear_momentum.y(),
      row.linear_momentum.z(), row.angular_momentum.x(), row.angular_momentum.y(), row.angular_momentum.z()};
  for (std::size_t c = 0; c < monitor.size(); ++c) f.conservation[c].push_back(monitor[c]);
  for (std::size_t s = 0; s < f.stage_names.size(); ++s) f.stage_seconds[s].push_back(row.stage_seconds[s]);
  ++f.rows;
  if (f.step.size() >= series_buffer_rows) {
    const hdf5::QuietErrors quiet;
    f.guarded([&] { f.write_buffered_rows(); });
  }
}

void RunFile::write_snapshot(const State& state, const ContactList& contacts, bool interrupted,
                             std::span<const std::pair<std::string_view, std::int64_t>> attributes) {
  Impl& f = *impl_;
  const hdf5::QuietErrors quiet;
  f.guarded([&] { write_snapshot_now(state, contacts, interrupted, attributes); });
}

void RunFile::set_status(RunStatus status, std::string_view reason) {
  Impl& f = *impl_;
  const hdf5::QuietErrors quiet;
  f.guarded([&] {
    hdf5::replace_attribute(f.run_group.get(), "status", run_status_name(status), f.path);
    hdf5::replace_attribute(f.run_group.get(), "stop_reason", reason, f.path);
  });
}

void RunFile::set_parameters(std::span<const RunParameter> parameters) {
  Impl& f = *impl_;
  const hdf5::QuietErrors quiet;
  f.guarded([&] {
    for (const RunParameter& parameter : parameters)
      run_file_detail::write_run_parameter(f.run_group.get(), parameter, f.path);
  });
}

void RunFile::write_snapshot_now(const State& state, const ContactList& contacts, bool interrupted,
                                 std::span<const std::pair<std::string_view, std::int64_t>> attributes) {
  Impl& f = *impl_;
  std::array<char, 16> name{};
  std::snprintf(name.data(), name.size(), "%06lld", static_cast<long long>(f.snapshots));
  Handle group = hdf5::create_group(f.snapshots_group.get(), name.data(), f.path);
  const hid_t g = group.get();
  hdf5::write_attribute(g, "time", state.time, f.path);
  hdf5::write_attribute(g, "step", state.step, f.path);
  hdf5::write_attribute(g, "interrupted", std::int64_t{interrupted ? 1 : 0}, f.path);
  for (const auto& [attribute, value] : attributes) hdf5::write_attribute(g, std::string(attribute), value, f.path);

  const std::size_t n = state.body_count();
  if (n != f.body_count || state.orientation.size() != n || state.velocity.size() != n ||
      state.angular_velocity.size() != n) {
    throw std::invalid_argument(f.path.string() + ": snapshot of a state with " + std::to_string(n) +
                                " bodies (or arrays of different sizes), the model has " +
                                std::to_string(f.body_count));
  }
  run_file_detail::write_state(g, state, f.path);
  run_file_detail::write_contacts(g, contacts, f.angular_impulses, f.path);
  f.snapshot_time_column->append(&state.time, 1, f.path);
  f.snapshot_step_column->append(&state.step, 1, f.path);
  f.snapshot_times.push_back(state.time);
  f.last_snapshot_step = state.step;
  ++f.snapshots;
}

void RunFile::flush() {
  Impl& f = *impl_;
  const hdf5::QuietErrors quiet;
  f.guarded([&] {
    f.write_buffered_rows();
    hdf5::check(H5Fflush(f.file.get(), H5F_SCOPE_LOCAL), f.path, "cannot flush");
  });
}

const fs::path& RunFile::path() const { return impl_->path; }
std::int64_t RunFile::snapshot_count() const { return impl_->snapshots; }
std::int64_t RunFile::series_rows() const { return impl_->rows; }
const std::vector<double>& RunFile::snapshot_times() const { return impl_->snapshot_times; }
std::int64_t RunFile::last_snapshot_step() const { return impl_->last_snapshot_step; }

}  // namespace rubble
