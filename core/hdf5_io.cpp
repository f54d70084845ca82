#include "core/hdf5_io.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <vector>

namespace rubble::hdf5 {
namespace {

static_assert(sizeof(hsize_t) == sizeof(std::uint64_t), "hsize_t is 64-bit in HDF5 1.10");

herr_t take_innermost(unsigned n, const H5E_error2_t* error, void* client) {
  // Walked upward: n == 0 is the most specific entry (the one that says what went wrong).
  if (n == 0 && error != nullptr && error->desc != nullptr) *static_cast<std::string*>(client) = error->desc;
  return 0;
}

std::string where(const std::filesystem::path& file, std::string_view what) {
  return file.string() + ": " + std::string(what);
}

/// Variable-length UTF-8 string type (what h5py reads as str).
Handle utf8_string_type(const std::filesystem::path& file) {
  Handle type = own(H5Tcopy(H5T_C_S1), H5Tclose, file, "string type");
  check(H5Tset_size(type.get(), H5T_VARIABLE), file, "string type");
  check(H5Tset_cset(type.get(), H5T_CSET_UTF8), file, "string type");
  return type;
}

hsize_t element_count(std::span<const hsize_t> dims) {
  return std::accumulate(dims.begin(), dims.end(), hsize_t{1}, [](hsize_t a, hsize_t b) { return a * b; });
}

/// Rows per chunk of a filtered dataset: a chunk stays under HDF5's 4 GiB limit for any row size
/// used here (at most a few doubles a row) and a damaged chunk names a small part of the file.
constexpr hsize_t filtered_chunk_rows = 65536;

/// Adds the filters of `storage` to chunked dataset-creation properties, in the documented order.
void add_filters(hid_t properties, const Storage& storage, const std::filesystem::path& file, const std::string& name) {
  if (storage.gzip_level > 0) {
    if (storage.shuffle) check(H5Pset_shuffle(properties), file, "shuffle filter of '" + name + "'");
    check(H5Pset_deflate(properties, static_cast<unsigned>(storage.gzip_level)), file, "compression of '" + name + "'");
  }
  if (storage.fletcher32) check(H5Pset_fletcher32(properties), file, "checksum of '" + name + "'");
}

bool filtered(const Storage& storage) { return storage.fletcher32 || storage.gzip_level > 0; }

void write_array(hid_t parent, const std::string& name, hid_t file_type, hid_t memory_type, const void* data,
                 std::size_t size, std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage) {
  if (element_count(dims) != size) {
    throw std::invalid_argument(where(file, "dataset '" + name + "': data size does not match its shape"));
  }
  // No dimensions: a scalar dataset (one value).
  Handle space =
      own(dims.empty() ? H5Screate(H5S_SCALAR) : H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
          H5Sclose, file, "dataspace of '" + name + "'");
  Handle properties = own(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, "dataset properties");
  if (filtered(storage) && size > 0 && !dims.empty()) {
    std::vector<hsize_t> chunk(dims.begin(), dims.end());
    chunk[0] = std::min(chunk[0], filtered_chunk_rows);
    check(H5Pset_chunk(properties.get(), static_cast<int>(chunk.size()), chunk.data()), file,
          "chunking of '" + name + "'");
    add_filters(properties.get(), storage, file, name);
  }
  Handle dataset =
      own(H5Dcreate2(parent, name.c_str(), file_type, space.get(), H5P_DEFAULT, properties.get(), H5P_DEFAULT),
          H5Dclose, file, "cannot create dataset '" + name + "'");
  // A zero-size dataset has nothing to write, but it exists with its shape (h5py reads it).
  if (size > 0) {
    check(H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), file,
          "cannot write dataset '" + name + "'");
  }
}

template <typename T>
Array<T> read_array(hid_t parent, const std::string& name, hid_t memory_type, const std::filesystem::path& file) {
  if (!exists(parent, name)) throw std::runtime_error(where(file, "missing dataset '" + name + "'"));
  Handle dataset = own(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), H5Dclose, file, "cannot open '" + name + "'");
  Handle space = own(H5Dget_space(dataset.get()), H5Sclose, file, "dataspace of '" + name + "'");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) throw std::runtime_error(where(file, "dataset '" + name + "' has no simple shape"));
  Array<T> array;
  array.dims.resize(static_cast<std::size_t>(rank));
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), array.dims.data(), nullptr);
  array.values.resize(static_cast<std::size_t>(element_count(array.dims)));
  if (!array.values.empty()) {
    check(H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, array.values.data()), file,
          "cannot read dataset '" + name + "'");
  }
  return array;
}

}  // namespace

std::string last_error_message() {
  std::string message;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, take_innermost, &message);
  return message;
}

void check(herr_t status, const std::filesystem::path& file, std::string_view what) {
  if (status >= 0) return;
  const std::string detail = last_error_message();
  throw std::runtime_error(where(file, what) + (detail.empty() ? "" : ": " + detail));
}

Handle own(hid_t id, Handle::Closer closer, const std::filesystem::path& file, std::string_view what) {
  if (id < 0) check(-1, file, what);
  return Handle(id, closer);
}

Handle create_file(const std::filesystem::path& path, ChunkIndex index) {
  // Not HDF5 1.10's newer format (H5Pset_libver_bounds), whose array chunk indexes are smaller
  // still: its files carry a "being written" flag that outlives a killed writer, after which
  // neither h5py nor a resumed run opens the file until `h5clear -s`.
  Handle creation = own(H5Pcreate(H5P_FILE_CREATE), H5Pclose, path, "file creation properties");
  if (index == ChunkIndex::small) check(H5Pset_istore_k(creation.get(), 1), path, "chunk index node size");
  hid_t id = -1;
  H5E_BEGIN_TRY { id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, creation.get(), H5P_DEFAULT); }
  H5E_END_TRY;
  return own(id, H5Fclose, path, "cannot create HDF5 file");
}

Handle open_file(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error(where(path, "no such file"));
  hid_t id = -1;
  H5E_BEGIN_TRY { id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT); }
  H5E_END_TRY;
  return own(id, H5Fclose, path, "cannot open as an HDF5 file");
}

Handle create_group(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  Handle properties = own(H5Pcreate(H5P_GROUP_CREATE), H5Pclose, file, "group properties");
  check(H5Pset_link_creation_order(properties.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), file,
        "group properties");
  return own(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, properties.get(), H5P_DEFAULT), H5Gclose, file,
             "cannot create group '" + name + "'");
}

Handle open_group(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  if (!exists(parent, name)) throw std::runtime_error(where(file, "missing group '" + name + "'"));
  return own(H5Gopen2(parent, name.c_str(), H5P_DEFAULT), H5Gclose, file, "cannot open group '" + name + "'");
}

bool exists(hid_t parent, const std::string& name) {
  // H5Lexists checks one link; walk the path so that "a/b" with a missing "a" answers false.
  std::size_t start = 0;
  htri_t found = 1;
  H5E_BEGIN_TRY {
    while (found > 0) {
      const std::size_t slash = name.find('/', start);
      const std::string prefix = name.substr(0, slash);
      found = H5Lexists(parent, prefix.c_str(), H5P_DEFAULT);
      if (slash == std::string::npos) break;
      start = slash + 1;
    }
  }
  H5E_END_TRY;
  return found > 0;
}

namespace {
herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* client) {
  static_cast<std::vector<std::string>*>(client)->emplace_back(name);
  return 0;
}
}  // namespace

std::vector<std::string> link_names(hid_t group, const std::filesystem::path& file) {
  std::vector<std::string> names;
  unsigned order_flags = 0;
  Handle properties = own(H5Gget_create_plist(group), H5Pclose, file, "group properties");
  check(H5Pget_link_creation_order(properties.get(), &order_flags), file, "group properties");
  const H5_index_t index = (order_flags & H5P_CRT_ORDER_INDEXED) != 0 ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  hsize_t position = 0;
  check(H5Literate(group, index, H5_ITER_INC, &position, collect_name, &names), file, "cannot list group");
  return names;
}

void write_doubles(hid_t parent, const std::string& name, std::span<const double> data, std::span<const hsize_t> dims,
                   const std::filesystem::path& file, Storage storage) {
  write_array(parent, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, data.data(), data.size(), dims, file, storage);
}
void write_int64s(hid_t parent, const std::string& name, std::span<const std::int64_t> data,
                  std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage) {
  write_array(parent, name, H5T_STD_I64LE, H5T_NATIVE_INT64, data.data(), data.size(), dims, file, storage);
}
void write_int32s(hid_t parent, const std::string& name, std::span<const std::int32_t> data,
                  std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage) {
  write_array(parent, name, H5T_STD_I32LE, H5T_NATIVE_INT32, data.data(), data.size(), dims, file, storage);
}
void write_int8s(hid_t parent, const std::string& name, std::span<const std::int8_t> data,
                 std::span<const hsize_t> dims, const std::filesystem::path& file, Storage storage) {
  write_array(parent, name, H5T_STD_I8LE, H5T_NATIVE_INT8, data.data(), data.size(), dims, file, storage);
}

void write_string(hid_t parent, const std::string& name, std::string_view text, const std::filesystem::path& file) {
  Handle type = utf8_string_type(file);
  Handle space = own(H5Screate(H5S_SCALAR), H5Sclose, file, "scalar dataspace");
  Handle dataset = own(H5Dcreate2(parent, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                       H5Dclose, file, "cannot create dataset '" + name + "'");
  const std::string owned(text);
  const char* pointer = owned.c_str();
  check(H5Dwrite(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &pointer), file,
        "cannot write dataset '" + name + "'");
}

void write_strings(hid_t parent, const std::string& name, std::span<const std::string> texts,
                   const std::filesystem::path& file) {
  Handle type = utf8_string_type(file);
  std::vector<const char*> pointers;
  for (const std::string& text : texts) pointers.push_back(text.c_str());
  const hsize_t dims[1] = {texts.size()};
  Handle space = own(H5Screate_simple(1, dims, nullptr), H5Sclose, file, "dataspace");
  Handle dataset = own(H5Dcreate2(parent, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                       H5Dclose, file, "cannot create dataset '" + name + "'");
  if (!pointers.empty()) {
    check(H5Dwrite(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, pointers.data()), file,
          "cannot write dataset '" + name + "'");
  }
}

namespace {
void write_scalar_attribute(hid_t object, const std::string& name, hid_t file_type, hid_t memory_type,
                            const void* value, const std::filesystem::path& file) {
  Handle space = own(H5Screate(H5S_SCALAR), H5Sclose, file, "scalar dataspace");
  Handle attribute = own(H5Acreate2(object, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                         file, "cannot create attribute '" + name + "'");
  check(H5Awrite(attribute.get(), memory_type, value), file, "cannot write attribute '" + name + "'");
}
}  // namespace

void write_attribute(hid_t object, const std::string& name, double value, const std::filesystem::path& file) {
  write_scalar_attribute(object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value, file);
}
void write_attribute(hid_t object, const std::string& name, std::int64_t value, const std::filesystem::path& file) {
  write_scalar_attribute(object, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value, file);
}
void write_attribute(hid_t object, const std::string& name, std::string_view value, const std::filesystem::path& file) {
  Handle type = utf8_string_type(file);
  const std::string owned(value);
  const char* pointer = owned.c_str();
  write_scalar_attribute(object, name, type.get(), type.get(), &pointer, file);
}
void write_attribute(hid_t object, const std::string& name, std::span<const std::string> values,
                     const std::filesystem::path& file) {
  Handle type = utf8_string_type(file);
  std::vector<const char*> pointers;
  for (const std::string& value : values) pointers.push_back(value.c_str());
  const hsize_t dims[1] = {values.size()};
  Handle space = own(H5Screate_simple(1, dims, nullptr), H5Sclose, file, "dataspace");
  Handle attribute = own(H5Acreate2(object, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                         file, "cannot create attribute '" + name + "'");
  if (!pointers.empty()) {
    check(H5Awrite(attribute.get(), type.get(), pointers.data()), file, "cannot write attribute '" + name + "'");
  }
}

void write_attribute_on(hid_t parent, const std::string& object_name, const std::string& name, std::string_view value,
                        const std::filesystem::path& file) {
  Handle type = utf8_string_type(file);
  Handle space = own(H5Screate(H5S_SCALAR), H5Sclose, file, "scalar dataspace");
  Handle attribute = own(H5Acreate_by_name(parent, object_name.c_str(), name.c_str(), type.get(), space.get(),
                                           H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                         H5Aclose, file, "cannot create attribute '" + name + "' of '" + object_name + "'");
  const std::string owned(value);
  const char* pointer = owned.c_str();
  check(H5Awrite(attribute.get(), type.get(), &pointer), file, "cannot write attribute '" + name + "'");
}

void replace_attribute(hid_t object, const std::string& name, std::string_view value,
                       const std::filesystem::path& file) {
  if (H5Aexists(object, name.c_str()) > 0) {
    check(H5Adelete(object, name.c_str()), file, "cannot replace attribute '" + name + "'");
  }
  write_attribute(object, name, value, file);
}

Array<double> read_doubles(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  return read_array<double>(parent, name, H5T_NATIVE_DOUBLE, file);
}
Array<std::int64_t> read_int64s(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  return read_array<std::int64_t>(parent, name, H5T_NATIVE_INT64, file);
}

namespace {
/// Reads a string from a dataset or attribute whose type is `stored`, with `read(memory_type, buffer)`.
template <typename Read>
std::string read_one_string(hid_t stored, Read read, const std::filesystem::path& file, const std::string& name) {
  if (H5Tget_class(stored) != H5T_STRING) throw std::runtime_error(where(file, "'" + name + "' is not a string"));
  if (H5Tis_variable_str(stored) > 0) {
    Handle type = utf8_string_type(file);
    char* pointer = nullptr;
    check(read(type.get(), &pointer), file, "cannot read '" + name + "'");
    std::string text = pointer != nullptr ? pointer : "";
    H5free_memory(pointer);
    return text;
  }
  const std::size_t size = H5Tget_size(stored);
  std::string text(size, '\0');
  Handle type = own(H5Tcopy(stored), H5Tclose, file, "string type");
  check(read(type.get(), text.data()), file, "cannot read '" + name + "'");
  text.resize(text.find('\0') == std::string::npos ? size : text.find('\0'));
  return text;
}
}  // namespace

std::string read_string(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  if (!exists(parent, name)) throw std::runtime_error(where(file, "missing dataset '" + name + "'"));
  Handle dataset = own(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), H5Dclose, file, "cannot open '" + name + "'");
  Handle stored = own(H5Dget_type(dataset.get()), H5Tclose, file, "type of '" + name + "'");
  return read_one_string(
      stored.get(),
      [&](hid_t memory_type, void* buffer) {
        return H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer);
      },
      file, name);
}

std::vector<std::string> read_strings(hid_t parent, const std::string& name, const std::filesystem::path& file) {
  if (!exists(parent, name)) throw std::runtime_error(where(file, "missing dataset '" + name + "'"));
  Handle dataset = own(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), H5Dclose, file, "cannot open '" + name + "'");
  Handle space = own(H5Dget_space(dataset.get()), H5Sclose, file, "dataspace of '" + name + "'");
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count < 0) check(-1, file, "dataspace of '" + name + "'");
  std::vector<char*> pointers(static_cast<std::size_t>(count), nullptr);
  std::vector<std::string> texts;
  if (count == 0) return texts;
  Handle type = utf8_string_type(file);
  check(H5Dread(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, pointers.data()), file,
        "cannot read '" + name + "' as variable-length strings");
  for (char* pointer : pointers) {
    texts.emplace_back(pointer != nullptr ? pointer : "");
    H5free_memory(pointer);
  }
  return texts;
}

double read_double_attribute(hid_t object, const std::string& name, const std::filesystem::path& file) {
  if (H5Aexists(object, name.c_str()) <= 0) throw std::runtime_error(where(file, "missing attribute '" + name + "'"));
  Handle attribute = own(H5Aopen(object, name.c_str(), H5P_DEFAULT), H5Aclose, file, "cannot open '" + name + "'");
  double value = 0.0;
  check(H5Aread(attribute.get(), H5T_NATIVE_DOUBLE, &value), file, "cannot read attribute '" + name + "'");
  return value;
}

std::string read_string_attribute(hid_t object, const std::string& name, const std::filesystem::path& file) {
  if (H5Aexists(object, name.c_str()) <= 0) throw std::runtime_error(where(file, "missing attribute '" + name + "'"));
  Handle attribute = own(H5Aopen(object, name.c_str(), H5P_DEFAULT), H5Aclose, file, "cannot open '" + name + "'");
  Handle stored = own(H5Aget_type(attribute.get()), H5Tclose, file, "type of '" + name + "'");
  return read_one_string(
      stored.get(), [&](hid_t memory_type, void* buffer) { return H5Aread(attribute.get(), memory_type, buffer); },
      file, name);
}

ExtendableColumn::ExtendableColumn(hid_t parent, const std::string& name, hid_t type, hsize_t chunk_rows,
                                   const std::filesystem::path& file, Storage storage)
    : type_(type), name_(name) {
  const hsize_t dims[1] = {0};
  const hsize_t max_dims[1] = {H5S_UNLIMITED};
  Handle space = own(H5Screate_simple(1, dims, max_dims), H5Sclose, file, "dataspace of '" + name + "'");
  Handle properties = own(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, "dataset properties");
  const hsize_t chunk[1] = {chunk_rows};
  check(H5Pset_chunk(properties.get(), 1, chunk), file, "chunking of '" + name + "'");
  add_filters(properties.get(), storage, file, name);
  dataset_ = own(H5Dcreate2(parent, name.c_str(), type, space.get(), H5P_DEFAULT, properties.get(), H5P_DEFAULT),
                 H5Dclose, file, "cannot create dataset '" + name + "'");
}

ExtendableColumn ExtendableColumn::open_truncated(hid_t parent, const std::string& name, hid_t type, hsize_t keep_rows,
                                                  const std::filesystem::path& file) {
  ExtendableColumn column;
  column.type_ = type;
  column.name_ = name;
  column.dataset_ = own(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), H5Dclose, file, "missing dataset '" + name + "'");
  Handle space = own(H5Dget_space(column.dataset_.get()), H5Sclose, file, "dataspace of '" + name + "'");
  if (H5Sget_simple_extent_ndims(space.get()) != 1) {
    throw std::runtime_error(file.string() + ": '" + name + "' is not a 1-D column");
  }
  hsize_t rows = 0;
  check(H5Sget_simple_extent_dims(space.get(), &rows, nullptr), file, "dataspace of '" + name + "'");
  column.size_ = std::min(rows, keep_rows);
  if (column.size_ != rows) {
    const hsize_t new_size[1] = {column.size_};
    check(H5Dset_extent(column.dataset_.get(), new_size), file, "cannot truncate '" + name + "'");
  }
  return column;
}

void ExtendableColumn::append(const void* data, std::size_t count, const std::filesystem::path& file) {
  if (count == 0) return;
  const hsize_t new_size[1] = {size_ + count};
  check(H5Dset_extent(dataset_.get(), new_size), file, "cannot extend '" + name_ + "'");
  Handle file_space = own(H5Dget_space(dataset_.get()), H5Sclose, file, "dataspace of '" + name_ + "'");
  const hsize_t start[1] = {size_};
  const hsize_t rows[1] = {count};
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, rows, nullptr), file,
        "selection in '" + name_ + "'");
  Handle memory_space = own(H5Screate_simple(1, rows, nullptr), H5Sclose, file, "dataspace");
  check(H5Dwrite(dataset_.get(), type_, memory_space.get(), file_space.get(), H5P_DEFAULT, data), file,
        "cannot write to '" + name_ + "'");
  size_ += count;
}

}  // namespace rubble::hdf5
