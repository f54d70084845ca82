#pragma once
// Small RAII and typed helpers over the HDF5 C API, shared by every file format rubble reads or
// writes (run files in postprocessing/, FCLib problems in nlgs_solver/, `rubble gravity` in apps/).
// It includes hdf5.h, so only .cpp files include it; its own library, rubble_hdf5_io, is linked
// only by the folders that do HDF5 input/output.
#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rubble::hdf5 {

/// Owns one HDF5 identifier and closes it with the matching H5xclose on destruction.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);  ///< H5Fclose, H5Gclose, H5Dclose, ...
  Handle() = default;                ///< an empty handle (id -1)
  /// Takes ownership of `id` (which may be negative: then nothing is closed).
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, -1)), closer_(other.closer_) {}  ///< moves
  /// Closes this id, takes the other's.
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, -1);
      closer_ = other.closer_;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  /// Closes the id now; returns the closer's status (negative on failure, e.g. a failed flush).
  herr_t reset() {
    herr_t status = 0;
    if (id_ >= 0 && closer_ != nullptr) status = closer_(id_);
    id_ = -1;
    return status;
  }
  /// The raw identifier.
  hid_t get() const { return id_; }
  /// True if the handle holds a valid id.
  explicit operator bool() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  Closer closer_ = nullptr;
};

/// Turns off HDF5's clean-up at process exit (H5dont_atexit); call before any other HDF5 call.
/// That clean-up closes the files left open, and HDF5 1.10 crashes (SIGSEGV in H5F__close_cb)
/// on a file whose close already failed, e.g. on a full disk. rubble closes every file it opens
/// through Handle (RAII), so the clean-up has nothing else to do.
inline void skip_library_cleanup_at_exit() { H5dont_atexit(); }

/// While alive, HDF5 does not print its error stack on stderr (we throw with the message instead).
/// Restores the previous error handler on destruction.
class QuietErrors {
 public:
  QuietErrors() {
    H5Eget_auto2(H5E_DEFAULT, &function_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietErrors() { H5Eset_auto2(H5E_DEFAULT, function_, data_); }
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;

 private:
  H5E_auto2_t function_ = nullptr;
  void* data_ = nullptr;
};

/// The innermost message on HDF5's error stack (e.g. "unable to open file"), or "".
std::string last_error_message();

/// Throws std::runtime_error("<file>: <what>: <HDF5 message>") if `status` < 0.
void check(herr_t status, const std::filesystem::path& file, std::string_view what);
/// Wraps an id: throws like check() if it is negative, otherwise returns an owning handle.
Handle own(hid_t id, Handle::Closer closer, const std::filesystem::path& file, std::string_view what);

/// The B-tree that indexes a file's chunked datasets.
enum class ChunkIndex {
  /// HDF5's default: nodes of 64 entries, 2 kB or more for every chunked dataset however few its
  /// chunks.
  standard,
  /// Nodes of 2 entries (H5Pset_istore_k 1, the least): for files of many small datasets of one
  /// or a few chunks each (a run file's snapshots), where the default nodes were a third of the
  /// file. Readable by every HDF5 since 1.8.
  small,
};

/// Creates (truncates) an HDF5 file; throws with the path on failure. Errors are not printed.
Handle create_file(const std::filesystem::path& path, ChunkIndex index = ChunkIndex::standard);
/// Opens an HDF5 file read-only; throws with the path on failure.
Handle open_file(const std::filesystem::path& path);

/// Creates a group (and tracks its links' creation order).
Handle create_group(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// Opens an existing group; throws "missing group" if it is not there.
Handle open_group(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// True if `name` (a path relative to parent) is a link in the file.
bool exists(hid_t parent, const std::string& name);
/// Names of the links in a group, in their creation order if tracked, else by name.
std::vector<std::string> link_names(hid_t group, const std::filesystem::path& file);

/// How a numeric dataset is stored. Any filter makes it chunked (at most 65 536 rows a chunk, so
/// that a chunk stays under HDF5's 4 GiB limit and a damaged chunk names a small part of the file);
/// empty datasets have nothing to filter and stay contiguous. Filters run in the order shuffle,
/// deflate, checksum on writing, so the checksum covers the bytes on disk and is verified first on
/// reading.
struct Storage {
  /// HDF5's Fletcher-32 checksum on every chunk, verified by every read: a damaged chunk fails to
  /// read with "data error detected by fletcher32 checksum" instead of returning wrong numbers.
  bool fletcher32 = false;
  /// Deflate (gzip) level, 1 (fast) to 9 (small); 0: no compression. Read by every HDF5 reader
  /// (h5py, h5dump, ParaView), as gzip is built into the HDF5 library.
  int gzip_level = 0;
  /// Byte shuffle before deflate (groups the bytes of equal significance: doubles of similar
  /// magnitude then compress much better). Only with gzip_level > 0.
  bool shuffle = false;
};

/// Writes a dataset of shape dims (row-major) from `data` (size = product of dims; may be 0; no dims: a
/// scalar).
void write_doubles(hid_t parent, const std::string& name, std::span<const double> data, std::span<const hsize_t> dims,
                   const std::filesystem::path& file, Storage storage = {});
/// Same for 64-bit integers.
void write_int64s(hid_t parent, const std::string& name, std::span<const std::int64_t> data,
                  std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage = {});
/// Same for 32-bit integers.
void write_int32s(hid_t parent, const std::string& name, std::span<const std::int32_t> data,
                  std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage = {});
/// Same for 8-bit integers.
void write_int8s(hid_t parent, const std::string& name, std::span<const std::int8_t> data,
                 std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage = {});
/// A scalar variable-length UTF-8 string dataset.
void write_string(hid_t parent, const std::string& name, std::string_view text, const std::filesystem::path& file);
/// A 1-D dataset of variable-length UTF-8 strings.
void write_strings(hid_t parent, const std::string& name, std::span<const std::string> texts,
                   const std::filesystem::path& file);

/// Scalar attributes on an object.
void write_attribute(hid_t object, const std::string& name, double value, const std::filesystem::path& file);
/// Scalar 64-bit integer attribute.
void write_attribute(hid_t object, const std::string& name, std::int64_t value, const std::filesystem::path& file);
/// Variable-length UTF-8 string attribute.
void write_attribute(hid_t object, const std::string& name, std::string_view value, const std::filesystem::path& file);
/// 1-D attribute of variable-length UTF-8 strings.
void write_attribute(hid_t object, const std::string& name, std::span<const std::string> values,
                     const std::filesystem::path& file);
/// Variable-length UTF-8 string attribute on the object `object_name` (a path relative to
/// `parent`), e.g. the units of a dataset just written by name.
void write_attribute_on(hid_t parent, const std::string& object_name, const std::string& name, std::string_view value,
                        const std::filesystem::path& file);
/// Replaces a scalar string attribute (creates it if missing): for values that change while the
/// file is written, such as a run's status.
void replace_attribute(hid_t object, const std::string& name, std::string_view value,
                       const std::filesystem::path& file);

/// A dataset read back: its shape and its values converted to the requested type.
template <typename T>
struct Array {
  std::vector<hsize_t> dims;  ///< shape
  std::vector<T> values;      ///< row-major
  /// Number of rows (dims[0]), 1 for a scalar.
  std::size_t rows() const { return dims.empty() ? 1 : static_cast<std::size_t>(dims[0]); }
};

/// Reads a numeric dataset as doubles (HDF5 converts the type); throws if missing.
Array<double> read_doubles(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// Reads a numeric dataset as 64-bit integers; throws if missing.
Array<std::int64_t> read_int64s(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// Reads a scalar string dataset (variable or fixed length).
std::string read_string(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// Reads a 1-D string dataset (variable length).
std::vector<std::string> read_strings(hid_t parent, const std::string& name, const std::filesystem::path& file);
/// Reads a scalar numeric attribute as double.
double read_double_attribute(hid_t object, const std::string& name, const std::filesystem::path& file);
/// Reads a string attribute (scalar, variable or fixed length).
std::string read_string_attribute(hid_t object, const std::string& name, const std::filesystem::path& file);

/// A 1-D dataset that grows by appending (chunked, unlimited maximum size).
class ExtendableColumn {
 public:
  /// Creates `name` in `parent` with element type `type` (a predefined native type such as
  /// H5T_NATIVE_DOUBLE), chunks of `chunk_rows` rows, stored with `storage`'s filters.
  ExtendableColumn(hid_t parent, const std::string& name, hid_t type, hsize_t chunk_rows,
                   const std::filesystem::path& file, Storage storage = {});
  /// Appends `count` elements of the column's type read from `data`.
  void append(const void* data, std::size_t count, const std::filesystem::path& file);
  /// Opens the existing column `name` of `parent` (made by the constructor above) and cuts it to
  /// its first `keep_rows` rows (or keeps it whole if it is shorter); appends continue after
  /// them. For resuming a run from a checkpoint (RunFile::reopen).
  static ExtendableColumn open_truncated(hid_t parent, const std::string& name, hid_t type, hsize_t keep_rows,
                                         const std::filesystem::path& file);
  /// Current length.
  hsize_t size() const { return size_; }

 private:
  ExtendableColumn() = default;
  Handle dataset_;
  hid_t type_ = -1;
  hsize_t size_ = 0;
  std::string name_;
};

}  // namespace rubble::hdf5
