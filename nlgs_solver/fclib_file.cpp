#include "nlgs_solver/fclib_file.hpp"

#include "core/hdf5_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <system_error>
#include <tuple>

namespace rubble {
namespace {

using hdf5::Handle;
using QuietHdf5 = hdf5::QuietErrors;

/// A file opened for reading, with the file name for messages.
struct Reader {
  std::string name;
  hid_t file;

  [[noreturn]] void fail(const std::string& dataset, const std::string& what) const {
    throw FclibFileError(name + ": " + dataset + ": " + what);
  }

  /// True when every link on the path exists (H5Lexists must be asked one level at a time).
  bool exists(const std::string& path) const {
    std::size_t position = 0;
    while ((position = path.find('/', position + 1)) != std::string::npos) {
      if (H5Lexists(file, path.substr(0, position).c_str(), H5P_DEFAULT) <= 0) return false;
    }
    return H5Lexists(file, path.c_str(), H5P_DEFAULT) > 0;
  }

  /// Opens a dataset and returns its element count (any rank).
  Handle open(const std::string& path, hsize_t& count) const {
    if (!exists(path)) fail(path, "missing dataset");
    Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT), H5Dclose);
    if (!dataset) fail(path, "not a dataset");
    Handle space(H5Dget_space(dataset.get()), H5Sclose);
    const hssize_t points = H5Sget_simple_extent_npoints(space.get());
    if (points < 0) fail(path, "cannot read the dataset's shape");
    count = static_cast<hsize_t>(points);
    return dataset;
  }

  /// Reads a numeric dataset as `memory_type` values (HDF5 converts the stored type).
  template <class T>
  std::vector<T> read(const std::string& path, hid_t memory_type, const char* expected) const {
    hsize_t count = 0;
    Handle dataset = open(path, count);
    Handle type(H5Dget_type(dataset.get()), H5Tclose);
    const H5T_class_t type_class = H5Tget_class(type.get());
    if (type_class != H5T_INTEGER && type_class != H5T_FLOAT) fail(path, std::string("expected ") + expected);
    std::vector<T> values(static_cast<std::size_t>(count));
    if (count > 0 && H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0) {
      fail(path, std::string("cannot read as ") + expected);
    }
    return values;
  }

  std::vector<double> doubles(const std::string& path) const {
    std::vector<double> values = read<double>(path, H5T_NATIVE_DOUBLE, "floating-point numbers");
    for (std::size_t k = 0; k < values.size(); ++k) {
      if (!std::isfinite(values[k])) fail(path, "entry " + std::to_string(k) + " is not finite");
    }
    return values;
  }

  std::vector<std::int64_t> integers(const std::string& path) const {
    hsize_t count = 0;
    {
      Handle dataset = open(path, count);
      Handle type(H5Dget_type(dataset.get()), H5Tclose);
      if (H5Tget_class(type.get()) != H5T_INTEGER) fail(path, "expected integers");
    }
    return read<std::int64_t>(path, H5T_NATIVE_INT64, "integers");
  }

  /// FCLib stores scalars as int32 arrays of length 1; a rank-0 dataset is accepted too.
  std::int64_t scalar(const std::string& path) const {
    const std::vector<std::int64_t> values = integers(path);
    if (values.size() != 1) fail(path, "expected one integer, found " + std::to_string(values.size()) + " values");
    return values[0];
  }

  /// A string dataset, fixed or variable length; "" when absent or not a string.
  std::string text(const std::string& path) const {
    if (!exists(path)) return "";
    Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT), H5Dclose);
    if (!dataset) return "";
    Handle type(H5Dget_type(dataset.get()), H5Tclose);
    if (H5Tget_class(type.get()) != H5T_STRING) return "";
    Handle space(H5Dget_space(dataset.get()), H5Sclose);
    if (H5Sget_simple_extent_npoints(space.get()) != 1) return "";
    if (H5Tis_variable_str(type.get()) > 0) {
      Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(memory.get(), H5T_VARIABLE);
      char* value = nullptr;
      if (H5Dread(dataset.get(), memory.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0 || value == nullptr)
        return "";
      std::string result(value);
      H5free_memory(value);
      return result;
    }
    const std::size_t size = H5Tget_size(type.get());
    std::string buffer(size, '\0');
    if (H5Dread(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()) < 0) return "";
    buffer.resize(std::strlen(buffer.c_str()));
    return buffer;
  }
};

/// Builds the CSR form from (row, column, value) entries: sorted by row then column, duplicates summed.
SparseMatrix compress_rows(int rows, int columns, std::vector<std::tuple<int, int, double>> entries) {
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    return std::tie(std::get<0>(a), std::get<1>(a)) < std::tie(std::get<0>(b), std::get<1>(b));
  });
  SparseMatrix W;
  W.rows = rows;
  W.columns = columns;
  W.row_start.assign(static_cast<std::size_t>(rows) + 1, 0);
  for (std::size_t e = 0; e < entries.size(); ++e) {
    const auto [row, column, value] = entries[e];
    if (!W.column.empty() && e > 0 && std::get<0>(entries[e - 1]) == row && std::get<1>(entries[e - 1]) == column) {
      W.value.back() += value;
      continue;
    }
    W.column.push_back(column);
    W.value.push_back(value);
    ++W.row_start[static_cast<std::size_t>(row) + 1];
  }
  std::partial_sum(W.row_start.begin(), W.row_start.end(), W.row_start.begin());
  return W;
}

/// Checks a compressed pointer array: starts at 0, non-decreasing, ends within the stored entries.
void check_pointers(const Reader& reader, const std::vector<std::int64_t>& p, std::size_t expected_size,
                    std::size_t stored, const char* kind) {
  const std::string path = "/fclib_local/W/p";
  if (p.size() != expected_size) {
    reader.fail(path, std::string("expected ") + std::to_string(expected_size) + " " + kind + " pointers, found " +
                          std::to_string(p.size()));
  }
  if (p.front() != 0) reader.fail(path, "the first pointer must be 0, found " + std::to_string(p.front()));
  for (std::size_t k = 1; k < p.size(); ++k) {
    if (p[k] < p[k - 1]) reader.fail(path, "pointers decrease at entry " + std::to_string(k));
  }
  if (static_cast<std::size_t>(p.back()) > stored) {
    reader.fail(path, "the last pointer (" + std::to_string(p.back()) + ") exceeds the " + std::to_string(stored) +
                          " stored entries of i and x");
  }
}

void write_dataset(hid_t location, const std::string& file, const std::string& path, hid_t file_type, hid_t memory_type,
                   const void* data, hsize_t count) {
  Handle space(H5Screate_simple(1, &count, nullptr), H5Sclose);
  Handle dataset(H5Dcreate2(location, path.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                 H5Dclose);
  if (!dataset || (count > 0 && H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)) {
    throw FclibFileError(file + ": " + path + ": cannot write the dataset");
  }
}

void write_doubles(hid_t location, const std::string& file, const std::string& path, const std::vector<double>& v) {
  write_dataset(location, file, path, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, v.data(), v.size());
}

void write_ints(hid_t location, const std::string& file, const std::string& path, const std::vector<std::int32_t>& v) {
  write_dataset(location, file, path, H5T_STD_I32LE, H5T_NATIVE_INT32, v.data(), v.size());
}

void write_text(hid_t location, const std::string& file, const std::string& path, const std::string& value) {
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1));
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle dataset(H5Dcreate2(location, path.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                 H5Dclose);
  std::string buffer = value.empty() ? std::string(1, '\0') : value;
  if (!dataset || H5Dwrite(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()) < 0) {
    throw FclibFileError(file + ": " + path + ": cannot write the dataset");
  }
}

Handle create_file(const std::filesystem::path& file) {
  Handle handle(H5Fcreate(file.string().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!handle) throw FclibFileError(file.string() + ": cannot create the HDF5 file");
  return handle;
}

void create_group(hid_t file, const std::string& name, const std::string& path) {
  Handle group(H5Gcreate2(file, path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  if (!group) throw FclibFileError(name + ": " + path + ": cannot create the group");
}

Handle open_for_reading(const std::filesystem::path& file) {
  const std::string name = file.string();
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw FclibFileError(name + ": no such file");
  if (H5Fis_hdf5(name.c_str()) <= 0) throw FclibFileError(name + ": not an HDF5 file");
  Handle handle(H5Fopen(name.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!handle) throw FclibFileError(name + ": cannot open the HDF5 file");
  return handle;
}

/// /fclib_local/vectors: q (3 per contact) and mu (one per contact, >= 0), checked against each
/// other; spacedim (3 when absent) is checked first.
LocalProblem read_vectors(const Reader& reader) {
  const std::int64_t spacedim = reader.exists("/fclib_local/spacedim") ? reader.scalar("/fclib_local/spacedim") : 3;
  if (spacedim != 3)
    reader.fail("/fclib_local/spacedim", "expected 3 (3D contacts), found " + std::to_string(spacedim));

  LocalProblem problem;
  problem.q = reader.doubles("/fclib_local/vectors/q");
  problem.mu = reader.doubles("/fclib_local/vectors/mu");
  const std::size_t contacts = problem.mu.size();
  if (problem.q.size() != 3 * contacts) {
    reader.fail("/fclib_local/vectors/q", "expected 3 x " + std::to_string(contacts) +
                                              " (contacts in mu) = " + std::to_string(3 * contacts) +
                                              " entries, found " + std::to_string(problem.q.size()));
  }
  for (std::size_t k = 0; k < contacts; ++k) {
    if (problem.mu[k] < 0.0) reader.fail("/fclib_local/vectors/mu", "entry " + std::to_string(k) + " is negative");
  }
  return problem;
}

/// /fclib_local/W as stored: its shape m x n, the storage code nz and the arrays p, i, x.
struct StoredMatrix {
  std::int64_t m = 0;   ///< rows
  std::int64_t n = 0;   ///< columns
  std::int64_t nz = 0;  ///< -2 compressed row, -1 compressed column, >= 0 triplet (entry count)
  std::vector<std::int64_t> p, i;
  std::vector<double> x;
};

/// Reads /fclib_local/W: a 3 nc x 3 nc matrix (3 rows per contact), as many i as x.
StoredMatrix read_stored_matrix(const Reader& reader, std::size_t contacts) {
  StoredMatrix W;
  W.m = reader.scalar("/fclib_local/W/m");
  W.n = reader.scalar("/fclib_local/W/n");
  W.nz = reader.scalar("/fclib_local/W/nz");
  const auto size = static_cast<std::int64_t>(3 * contacts);
  if (W.m != size || W.n != size) {
    reader.fail("/fclib_local/W", "expected a " + std::to_string(size) + " x " + std::to_string(size) +
                                      " matrix (3 rows per contact), found m = " + std::to_string(W.m) +
                                      ", n = " + std::to_string(W.n));
  }
  W.p = reader.integers("/fclib_local/W/p");
  W.i = reader.integers("/fclib_local/W/i");
  W.x = reader.doubles("/fclib_local/W/x");
  if (W.i.size() != W.x.size()) {
    reader.fail("/fclib_local/W/i",
                "i has " + std::to_string(W.i.size()) + " entries but x has " + std::to_string(W.x.size()));
  }
  return W;
}

/// W's entries as (row, column, value), in the order stored.
using MatrixEntries = std::vector<std::tuple<int, int, double>>;

/// Checks that entry `entry` of an index array lies in [0, bound).
void check_index(const Reader& reader, std::int64_t value, std::int64_t bound, const char* dataset, std::size_t entry) {
  if (value < 0 || value >= bound) {
    reader.fail(dataset, "entry " + std::to_string(entry) + " = " + std::to_string(value) + " is outside [0, " +
                             std::to_string(bound) + ")");
  }
}

/// The entries of W stored compressed by row (nz = -2) or by column (nz = -1).
MatrixEntries compressed_entries(const Reader& reader, const StoredMatrix& W) {
  const bool by_row = W.nz == -2;
  const std::int64_t outer = by_row ? W.m : W.n;
  const std::int64_t inner = by_row ? W.n : W.m;
  check_pointers(reader, W.p, static_cast<std::size_t>(outer) + 1, W.i.size(), by_row ? "row" : "column");
  MatrixEntries entries;
  for (std::int64_t o = 0; o < outer; ++o) {
    for (std::int64_t e = W.p[static_cast<std::size_t>(o)]; e < W.p[static_cast<std::size_t>(o) + 1]; ++e) {
      const auto entry = static_cast<std::size_t>(e);
      check_index(reader, W.i[entry], inner, "/fclib_local/W/i", entry);
      const auto a = static_cast<int>(o), b = static_cast<int>(W.i[entry]);
      entries.emplace_back(by_row ? a : b, by_row ? b : a, W.x[entry]);
    }
  }
  return entries;
}

/// The entries of W stored as nz >= 0 triplets (i = row, p = column).
MatrixEntries triplet_entries(const Reader& reader, const StoredMatrix& W) {
  const auto count = static_cast<std::size_t>(W.nz);
  if (W.i.size() < count || W.p.size() < count) {
    reader.fail("/fclib_local/W", "triplet form with nz = " + std::to_string(W.nz) +
                                      " needs that many entries in i, p and x, found " +
                                      std::to_string(std::min(W.i.size(), W.p.size())));
  }
  MatrixEntries entries;
  for (std::size_t e = 0; e < count; ++e) {
    check_index(reader, W.i[e], W.m, "/fclib_local/W/i", e);
    check_index(reader, W.p[e], W.n, "/fclib_local/W/p", e);
    entries.emplace_back(static_cast<int>(W.i[e]), static_cast<int>(W.p[e]), W.x[e]);
  }
  return entries;
}

}  // namespace

LocalProblem read_fclib_local(const std::filesystem::path& file, FclibFileInfo* info) {
  const QuietHdf5 quiet;
  const Handle handle = open_for_reading(file);
  const Reader reader{file.string(), handle.get()};
  if (!reader.exists("/fclib_local")) reader.fail("/fclib_local", "missing group (not an FCLib local problem)");
  LocalProblem problem = read_vectors(reader);
  const StoredMatrix W = read_stored_matrix(reader, problem.mu.size());
  MatrixEntries entries;
  SparseStorage storage = SparseStorage::triplet;
  if (W.nz == -2 || W.nz == -1) {
    storage = W.nz == -2 ? SparseStorage::compressed_row : SparseStorage::compressed_column;
    entries = compressed_entries(reader, W);
  } else if (W.nz >= 0) {
    entries = triplet_entries(reader, W);
  } else {
    reader.fail("/fclib_local/W/nz", "expected -2 (compressed row), -1 (compressed column) or >= 0 (triplet), found " +
                                         std::to_string(W.nz));
  }
  problem.W = compress_rows(static_cast<int>(W.m), static_cast<int>(W.n), std::move(entries));
  if (info != nullptr) {
    info->title = reader.text("/fclib_local/info/title");
    info->description = reader.text("/fclib_local/info/description");
    info->storage = storage;
  }
  return problem;
}

void write_fclib_local(const std::filesystem::path& file, const LocalProblem& problem, SparseStorage storage,
                       const std::string& title) {
  const QuietHdf5 quiet;
  const std::string name = file.string();
  const SparseMatrix& W = problem.W;
  std::vector<std::int32_t> p, i;
  std::vector<double> x;
  std::int32_t nz = -2;
  if (storage == SparseStorage::compressed_row) {
    p.assign(W.row_start.begin(), W.row_start.end());
    i.assign(W.column.begin(), W.column.end());
    x = W.value;
  } else if (storage == SparseStorage::compressed_column) {
    nz = -1;
    // Transpose the CSR arrays: count per column, then scatter (rows stay sorted within a column).
    p.assign(static_cast<std::size_t>(W.columns) + 1, 0);
    for (int c : W.column) ++p[static_cast<std::size_t>(c) + 1];
    std::partial_sum(p.begin(), p.end(), p.begin());
    std::vector<std::int32_t> next(p.begin(), p.end() - 1);
    i.resize(W.value.size());
    x.resize(W.value.size());
    for (int row = 0; row < W.rows; ++row) {
      for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1];
           ++e) {
        const auto slot =
            static_cast<std::size_t>(next[static_cast<std::size_t>(W.column[static_cast<std::size_t>(e)])]++);
        i[slot] = row;
        x[slot] = W.value[static_cast<std::size_t>(e)];
      }
    }
  } else {
    nz = static_cast<std::int32_t>(W.value.size());
    for (int row = 0; row < W.rows; ++row) {
      for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1];
           ++e) {
        i.push_back(row);
        p.push_back(W.column[static_cast<std::size_t>(e)]);
        x.push_back(W.value[static_cast<std::size_t>(e)]);
      }
    }
  }
  const Handle handle = create_file(file);
  const hid_t f = handle.get();
  for (const char* group : {"/fclib_local", "/fclib_local/W", "/fclib_local/vectors", "/fclib_local/info"}) {
    create_group(f, name, group);
  }
  write_ints(f, name, "/fclib_local/W/m", {W.rows});
  write_ints(f, name, "/fclib_local/W/n", {W.columns});
  write_ints(f, name, "/fclib_local/W/nz", {nz});
  write_ints(f, name, "/fclib_local/W/nzmax", {static_cast<std::int32_t>(x.size())});
  write_ints(f, name, "/fclib_local/W/p", p);
  write_ints(f, name, "/fclib_local/W/i", i);
  write_doubles(f, name, "/fclib_local/W/x", x);
  write_doubles(f, name, "/fclib_local/vectors/q", problem.q);
  write_doubles(f, name, "/fclib_local/vectors/mu", problem.mu);
  write_ints(f, name, "/fclib_local/spacedim", {3});
  write_text(f, name, "/fclib_local/info/title", title);
}

void write_fclib_solution(const std::filesystem::path& file, const std::vector<double>& r,
                          const std::vector<double>& u) {
  const QuietHdf5 quiet;
  const Handle handle = create_file(file);
  write_doubles(handle.get(), file.string(), "r", r);
  write_doubles(handle.get(), file.string(), "u", u);
}

void read_fclib_solution(const std::filesystem::path& file, std::vector<double>& r, std::vector<double>& u) {
  const QuietHdf5 quiet;
  const Handle handle = open_for_reading(file);
  const Reader reader{file.string(), handle.get()};
  r = reader.doubles("r");
  u = reader.doubles("u");
  if (r.size() != u.size()) reader.fail("u", "r and u differ in length");
}

}  // namespace rubble
