// `rubble gravity IN.h5 [--method tree|direct] [--backend cpu|cuda] [--theta 0.5] [--order 2] [--out OUT.h5] ...`
// Reads `positions` (N x 3) and `masses` (N) from an HDF5 file, computes the self-gravity field
// with rubble::gravity, optionally writes `accelerations` (N x 3) and `potential` (N) to OUT.h5,
// and prints one JSON line (N, method, backend, theta, order, threads, build/walk/total seconds).
// Invalid input, or a backend that cannot run here (--backend cuda without a GPU), -> message on
// stderr naming the file or option and the problem, exit code 2; that includes coordinates or
// masses so large that the field would overflow (see max_coordinate). A non-finite acceleration
// or potential in the result is a numerical failure: exit code 3 naming the particle, no output
// file.

#include "core/hdf5_io.hpp"
#include <omp.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "core/input_error.hpp"
#include "gravity/gravity.hpp"
#include "simulation/memory_estimate.hpp"

namespace rubble::apps {
namespace {

struct GravityArguments {
  std::string input;
  std::string output;
  std::string method = "tree";
  std::string backend = "cpu";
  double theta = 0.5;
  int order = 2;
  double G = 6.674e-11;
  double softening = 0.0;
  int leaf_size = 0;   // 0: library default
  int group_size = 0;  // 0: library default
  int threads = 0;     // 0: OpenMP default
  std::string precision = "double";
};

/// Invalid input: reported on stderr, exit code 2.
struct BadInput : InputError {
  using InputError::InputError;
};

using hdf5::Handle;
using QuietHdf5 = hdf5::QuietErrors;

/// Bounds on |coordinate| (m) and on mass (kg) in the input: the tree's quadrupole moments grow as
/// m r^2 and are summed over N particles, and the field as G M / r^2; with |x| and m at most 1e60
/// those stay below 1e200 for any N a machine holds, where 1e308 overflows. The observable
/// universe is about 1e27 m across and 1e53 kg, so no physical input comes near.
constexpr double max_coordinate = 1e60;
constexpr double max_mass = 1e60;

/// A non-finite field: reported on stderr, exit code 3.
struct NonFiniteField : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Reads a numeric dataset as doubles and returns its dimensions. Throws BadInput.
std::vector<double> read_dataset(hid_t file, const std::string& path, const std::string& name,
                                 std::vector<hsize_t>& dims) {
  if (H5Lexists(file, name.c_str(), H5P_DEFAULT) <= 0) throw BadInput(path + ": missing dataset '" + name + "'");
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds) throw BadInput(path + ": '" + name + "' is not a dataset");
  Handle type(H5Dget_type(ds.get()), H5Tclose);
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_FLOAT && cls != H5T_INTEGER) throw BadInput(path + ": dataset '" + name + "' is not numeric");
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) throw BadInput(path + ": cannot read the shape of dataset '" + name + "'");
  dims.assign(static_cast<std::size_t>(rank), 0);
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  hsize_t count = 1;
  for (hsize_t d : dims) count = d == 0 ? 0 : (count > ~hsize_t{0} / d ? ~hsize_t{0} : count * d);
  // A dataset's shape costs nothing on disk (chunked, never written): check that it fits in
  // memory before allocating it (simulation/memory_estimate.hpp).
  const double bytes = 8.0 * static_cast<double>(count);
  if (const double available = available_memory(); available > 0.0 && bytes > 0.5 * available) {
    throw BadInput(
        fmt::format("{}: dataset '{}' has {} values ({:.3g} GB as doubles), more than half of the "
                    "{:.3g} GB of memory this process may use",
                    path, name, count, bytes / 1e9, available / 1e9));
  }
  std::vector<double> values(static_cast<std::size_t>(count));
  if (count > 0 && H5Dread(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
    throw BadInput(path + ": cannot read dataset '" + name + "' as double precision numbers");
  return values;
}

std::string shape_string(const std::vector<hsize_t>& dims) {
  std::string s = "(";
  for (std::size_t i = 0; i < dims.size(); ++i) s += (i ? ", " : "") + std::to_string(dims[i]);
  return s + (dims.size() == 1 ? ",)" : ")");
}

void write_dataset(hid_t file, const std::string& path, const char* name, const std::vector<hsize_t>& dims,
                   const std::vector<double>& values) {
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
  Handle ds(H5Dcreate2(file, name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  if (!ds ||
      (!values.empty() && H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0))
    throw std::runtime_error(path + ": cannot write dataset '" + name + "'");
}

void write_attribute(hid_t file, const char* name, double value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(file, name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (attr) H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &value);
}

/// The library's options from the command line, checked. Throws BadInput, also for a backend
/// that cannot run here: it fails fast, before the input is read, whatever the file.
gravity::GravityOptions gravity_options(const GravityArguments& args) {
  gravity::GravityOptions options;
  if (args.method == "tree")
    options.method = gravity::Method::tree;
  else if (args.method == "direct")
    options.method = gravity::Method::direct;
  else
    throw BadInput("--method must be 'tree' or 'direct', got '" + args.method + "'");
  if (args.backend == "cpu")
    options.backend = gravity::Backend::cpu;
  else if (args.backend == "cuda")
    options.backend = gravity::Backend::cuda;
  else
    throw BadInput("--backend must be 'cpu' or 'cuda', got '" + args.backend + "'");
  if (!(args.theta > 0) || !std::isfinite(args.theta))
    throw BadInput("--theta must be a finite number > 0, got " + std::to_string(args.theta));
  if (args.order != 1 && args.order != 2)
    throw BadInput("--order must be 1 (monopole) or 2 (quadrupole), got " + std::to_string(args.order));
  if (!std::isfinite(args.G) || !(args.G > 0)) throw BadInput("--G must be a finite number > 0");
  if (!(args.softening >= 0) || !std::isfinite(args.softening))
    throw BadInput("--softening must be a finite length >= 0");
  if (args.leaf_size < 0 || args.group_size < 0 || args.threads < 0)
    throw BadInput("--leaf-size, --group-size and --threads must be >= 0 (0: default)");
  options.theta = args.theta;
  options.order = args.order;
  options.G = args.G;
  if (args.softening > 0) options.softening = {gravity::Softening::Kind::plummer, args.softening};
  if (args.leaf_size > 0) options.leaf_size = args.leaf_size;
  if (args.group_size > 0) options.group_size = args.group_size;
  if (args.precision != "double" && args.precision != "single")
    throw BadInput("--precision must be double or single, got " + args.precision);
  if (args.precision == "single") options.precision = gravity::KernelPrecision::single_precision;
  const std::string unavailable = gravity::backend_unavailable_reason(options);
  if (!unavailable.empty()) throw BadInput("--backend " + args.backend + ": " + unavailable);
  return options;
}

/// The input particles: positions (N x 3, flat) and masses (N), in the file's order.
struct Particles {
  std::vector<double> positions;
  std::vector<double> masses;
};

/// Opens the input file for reading. Throws BadInput when it is missing or not HDF5.
Handle open_input(const std::string& in) {
  std::error_code ec;
  if (!std::filesystem::exists(in, ec)) throw BadInput(in + ": no such file");
  if (H5Fis_hdf5(in.c_str()) <= 0) throw BadInput(in + ": not an HDF5 file");
  Handle file(H5Fopen(in.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file) throw BadInput(in + ": cannot open the HDF5 file");
  return file;
}

/// Reads `positions` and `masses` from the open input file and checks their shapes and values:
/// finite, masses >= 0, and within max_coordinate and max_mass. Throws BadInput.
Particles read_particles(hid_t file, const std::string& in) {
  std::vector<hsize_t> pdims, mdims;
  Particles p;
  p.positions = read_dataset(file, in, "positions", pdims);
  p.masses = read_dataset(file, in, "masses", mdims);
  if (pdims.size() != 2 || pdims[1] != 3)
    throw BadInput(in + ": dataset 'positions' must have shape (N, 3), got " + shape_string(pdims));
  if (mdims.size() != 1 || mdims[0] != pdims[0])
    throw BadInput(in + ": dataset 'masses' must have shape (" + std::to_string(pdims[0]) +
                   ",) to match 'positions', got " + shape_string(mdims));
  const std::vector<double>& masses = p.masses;
  const std::vector<double>& positions = p.positions;
  for (std::size_t i = 0; i < masses.size(); ++i) {
    if (std::isnan(masses[i])) throw BadInput(in + ": masses[" + std::to_string(i) + "] is NaN");
    if (!std::isfinite(masses[i])) throw BadInput(in + ": masses[" + std::to_string(i) + "] is infinite");
    if (masses[i] < 0)
      throw BadInput(in + ": masses[" + std::to_string(i) + "] is negative (" + std::to_string(masses[i]) + ")");
  }
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i]))
      throw BadInput(in + ": positions[" + std::to_string(i / 3) + "][" + std::to_string(i % 3) + "] is not finite");
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (std::abs(positions[i]) > max_coordinate)
      throw BadInput(fmt::format(
          "{}: positions[{}][{}] = {:.6g} m: expected a coordinate of magnitude <= {:.0e} m (beyond it the field "
          "overflows double precision)",
          in, i / 3, i % 3, positions[i], max_coordinate));
  for (std::size_t i = 0; i < masses.size(); ++i)
    if (masses[i] > max_mass)
      throw BadInput(
          fmt::format("{}: masses[{}] = {:.6g} kg: expected <= {:.0e} kg (beyond it the field overflows "
                      "double precision)",
                      in, i, masses[i], max_mass));
  return p;
}

/// The computed field: accelerations (N x 3, flat), potential (N), the library's timings and the
/// wall seconds of the whole computation.
struct Field {
  std::vector<double> accelerations;
  std::vector<double> potential;
  gravity::FieldTimings timings;
  double seconds = 0.0;
};

/// Computes the field of the particles on themselves. Throws BadInput when the library refuses
/// the input, NonFiniteField naming the first particle whose field is not finite.
Field compute_checked_field(const gravity::GravityOptions& options, const Particles& particles, const std::string& in) {
  const std::vector<double>& positions = particles.positions;
  const std::size_t n = particles.masses.size();
  Field field;
  std::vector<double>& acc = field.accelerations;
  std::vector<double>& pot = field.potential;
  acc.resize(3 * n);
  pot.resize(n);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    field.timings = gravity::compute_field(options, positions, particles.masses, acc, pot);
  } catch (const gravity::GravityError& e) {
    throw BadInput(in + ": " + e.what());
  }
  field.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(acc[3 * i]) || !std::isfinite(acc[3 * i + 1]) || !std::isfinite(acc[3 * i + 2]) ||
        !std::isfinite(pot[i])) {
      throw NonFiniteField(
          fmt::format("{}: particle {} at ({:.6g}, {:.6g}, {:.6g}) m: acceleration ({}, {}, {}), potential {} (the "
                      "field overflows "
                      "double precision: a large --G, or particles very close together without --softening)",
                      in, i, positions[3 * i], positions[3 * i + 1], positions[3 * i + 2], acc[3 * i], acc[3 * i + 1],
                      acc[3 * i + 2], pot[i]));
    }
  }
  return field;
}

/// Writes the field and the options it was computed with to args.output. Returns exit_ok, or
/// exit_output_failure after saying why on stderr.
int write_field(const GravityArguments& args, const gravity::GravityOptions& options, const Field& field) {
  const std::size_t n = field.potential.size();
  Handle out(H5Fcreate(args.output.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!out) {
    std::cerr << "rubble gravity: output failure: " << args.output << ": cannot create the output file\n";
    return exit_output_failure;
  }
  try {
    write_dataset(out.get(), args.output, "accelerations", {n, 3}, field.accelerations);
    write_dataset(out.get(), args.output, "potential", {n}, field.potential);
    write_attribute(out.get(), "G", options.G);
    write_attribute(out.get(), "theta", options.theta);
    write_attribute(out.get(), "order", options.order);
    write_attribute(out.get(), "softening_length", args.softening);
    // HDF5 buffers the data; a full disk shows only when it is flushed and closed.
    if (H5Fflush(out.get(), H5F_SCOPE_LOCAL) < 0 || out.reset() < 0) {
      throw std::runtime_error(args.output + ": cannot flush the output file (disk full or I/O error?)");
    }
  } catch (const std::runtime_error& e) {
    std::cerr << "rubble gravity: output failure: " << e.what() << "\n";
    return exit_output_failure;
  }
  return exit_ok;
}

/// The one JSON line on stdout: what was computed, with what, and how long it took.
void print_summary(const GravityArguments& args, const gravity::GravityOptions& options, const Field& field) {
  nlohmann::json line = {{"N", field.potential.size()},
                         {"method", gravity::to_string(options.method)},
                         {"backend", gravity::to_string(options.backend)},
                         {"theta", options.theta},
                         {"order", options.order},
                         {"G", options.G},
                         {"softening", args.softening},
                         {"threads", omp_get_max_threads()},
                         {"build_seconds", field.timings.build_seconds},
                         {"walk_seconds", field.timings.walk_seconds},
                         {"seconds", field.seconds},
                         {"input", args.input},
                         {"output", args.output}};
  std::cout << line.dump() << std::endl;
}

int gravity_command(const GravityArguments& args) {
  const QuietHdf5 quiet;
  try {
    const gravity::GravityOptions options = gravity_options(args);
    // The input stays open until the output is written (an output path naming the input fails).
    const Handle file = open_input(args.input);
    const Particles particles = read_particles(file.get(), args.input);
    if (args.threads > 0) omp_set_num_threads(args.threads);
    const Field field = compute_checked_field(options, particles, args.input);
    if (!args.output.empty()) {
      if (const int code = write_field(args, options, field); code != exit_ok) return code;
    }
    print_summary(args, options, field);
  } catch (const InputError& e) {
    std::cerr << "rubble gravity: error: " << e.what() << "\n";
    return exit_bad_input;
  } catch (const NonFiniteField& e) {
    std::cerr << "rubble gravity: numerical failure: " << e.what() << "; no output written\n";
    return exit_numerical_failure;
  }
  return exit_ok;
}

}  // namespace

void register_gravity_command(CLI::App& app) {
  auto args = std::make_shared<GravityArguments>();
  CLI::App* cmd = app.add_subcommand(
      "gravity", "Self-gravity of N point masses from an HDF5 file (datasets positions (N,3), masses (N))");
  cmd->add_option("input", args->input, "HDF5 file with datasets 'positions' (N x 3) and 'masses' (N)")->required();
  cmd->add_option("--method", args->method, "tree (Barnes-Hut) or direct (exact O(N^2) sum)")->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "cpu, or cuda (a GPU: method direct only for now; exit 2 where it cannot run)")
      ->capture_default_str();
  cmd->add_option("--theta", args->theta, "Opening angle of the tree (> 0)")->capture_default_str();
  cmd->add_option("--order", args->order, "Multipole order: 1 monopole, 2 quadrupole")->capture_default_str();
  cmd->add_option("--out", args->output, "Output HDF5 file: datasets 'accelerations' (N x 3), 'potential' (N)");
  cmd->add_option("--G", args->G, "Gravitational constant (sets the unit system)")->capture_default_str();
  cmd->add_option("--softening", args->softening, "Plummer softening length (0: none)")->capture_default_str();
  cmd->add_option("--leaf-size", args->leaf_size, "Max particles per tree leaf (0: library default)");
  cmd->add_option("--group-size", args->group_size, "Max targets per tree walk group (0: library default)");
  cmd->add_option("--threads", args->threads, "OpenMP threads (0: OMP_NUM_THREADS or all cores)");
  cmd->add_option("--precision", args->precision,
                  "Arithmetic of the tree's kernels: double, or single (faster; each term within ~1e-6)")
      ->capture_default_str();
  cmd->callback([args] {
    const int code = gravity_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
