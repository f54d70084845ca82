#include "simulation/checkpoint.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <fmt/format.h>
#include <type_traits>
#include <utility>

namespace rubble {
namespace {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little, "checkpoints are written little-endian");

constexpr std::array<char, 8> magic{'R', 'U', 'B', 'B', 'L', 'E', 'C', 'K'};
constexpr std::size_t header_bytes = 8 + 4 + 4 + 8;  // magic, version, reserved, payload size
constexpr std::size_t trailer_bytes = 8;              // CRC-64

/// CRC-64/XZ table: reflected ECMA-182 polynomial 0x42F0E1EBA9EA3693 (reversed 0xC96C5795D7870F42).
constexpr std::array<std::uint64_t, 256> make_crc_table() {
  std::array<std::uint64_t, 256> table{};
  for (std::uint64_t i = 0; i < 256; ++i) {
    std::uint64_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0xC96C5795D7870F42ULL : c >> 1;
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint64_t, 256> crc_table = make_crc_table();

/// Where serialised bytes go: appended to a buffer (serialize_checkpoint, state_hash), only counted
/// (the payload size announced in the header before the payload is streamed), or streamed to a
/// file (write_checkpoint).
struct ByteBuffer {
  void append(const std::byte* p, std::size_t n) { bytes.insert(bytes.end(), p, p + n); }
  std::vector<std::byte> bytes;  ///< everything appended
};
struct ByteCounter {
  void append(const std::byte*, std::size_t n) { count += n; }
  std::uint64_t count = 0;  ///< bytes appended
};

/// Only the CRC-64 of the bytes, through a small buffer (state_hash: no copy of the state).
struct CrcSink {
  void append(const std::byte* p, std::size_t n) {
    while (n > 0) {
      const std::size_t room = std::min(n, buffer.size() - used);
      std::memcpy(buffer.data() + used, p, room);
      used += room;
      p += room;
      n -= room;
      if (used == buffer.size()) flush();
    }
  }
  void flush() {
    crc = crc64(std::span<const std::byte>(buffer.data(), used), crc);
    used = 0;
  }
  std::array<std::byte, 4096> buffer{};  ///< bytes not yet in crc
  std::size_t used = 0;                  ///< bytes in buffer
  std::uint64_t crc = 0;                 ///< CRC-64 of the bytes flushed so far
};

/// Writes values in native (little-endian) order to a sink with append(const std::byte*, size_t).
template <typename Sink>
class Writer {
 public:
  explicit Writer(Sink& sink) : sink_(sink) {}
  template <typename T>
    requires std::is_arithmetic_v<T>
  void put(T value) {
    sink_.append(reinterpret_cast<const std::byte*>(&value), sizeof(T));
  }
  void put(const Vec3& v) {
    put(v.x());
    put(v.y());
    put(v.z());
  }
  void put(const Mat3& m) {  // row by row
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) put(m(i, j));
  }
  void put(const Quat& q) {
    put(q.w());
    put(q.x());
    put(q.y());
    put(q.z());
  }
  void put(const std::string& text) {
    put(static_cast<std::uint64_t>(text.size()));
    sink_.append(reinterpret_cast<const std::byte*>(text.data()), text.size());
  }
  template <typename T>
  void put_array(const std::vector<T>& values) {
    put(static_cast<std::uint64_t>(values.size()));
    for (const T& v : values) put(v);
  }

 private:
  Sink& sink_;
};

/// Reads values back, checking every read against the end of the payload.
class Reader {
 public:
  Reader(std::span<const std::byte> bytes, const std::string& source) : bytes_(bytes), source_(source) {}

  template <typename T>
    requires std::is_arithmetic_v<T>
  T get() {
    need(sizeof(T), "a number");
    T value;
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  Vec3 vec3() {
    const double x = get<double>(), y = get<double>(), z = get<double>();
    return Vec3(x, y, z);
  }
  Mat3 mat3() {
    Mat3 m;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m(i, j) = get<double>();
    return m;
  }
  Quat quat() {
    const double w = get<double>(), x = get<double>(), y = get<double>(), z = get<double>();
    return Quat(w, x, y, z);
  }
  std::string text() {
    const std::uint64_t size = get<std::uint64_t>();
    need(size, "a string");
    std::string value(reinterpret_cast<const char*>(bytes_.data() + offset_), static_cast<std::size_t>(size));
    offset_ += static_cast<std::size_t>(size);
    return value;
  }
  /// Reads an array length and checks that `element_bytes` per element fit in what is left, so
  /// that a damaged length can never make us allocate absurd amounts.
  std::size_t length(std::size_t element_bytes, const char* what) {
    const std::uint64_t count = get<std::uint64_t>();
    if (element_bytes > 0 && count > (bytes_.size() - offset_) / element_bytes) {
      fail(fmt::format("{} has {} entries, more than the file can hold", what, count));
    }
    return static_cast<std::size_t>(count);
  }
  std::vector<Vec3> vec3_array(const char* what) {
    std::vector<Vec3> values(length(24, what));
    for (Vec3& v : values) v = vec3();
    return values;
  }
  bool at_end() const { return offset_ == bytes_.size(); }
  [[noreturn]] void fail(const std::string& message) const { throw CheckpointError(source_ + ": " + message); }

 private:
  void need(std::uint64_t size, const char* what) const {
    if (size > bytes_.size() - offset_) fail(fmt::format("truncated payload while reading {}", what));
  }
  std::span<const std::byte> bytes_;
  std::size_t offset_ = 0;
  const std::string& source_;
};

template <typename Sink>
void put_state(Writer<Sink>& out, const State& state) {
  out.put(state.time);
  out.put(state.step);
  out.put_array(state.position);
  out.put_array(state.orientation);
  out.put_array(state.velocity);
  out.put_array(state.angular_velocity);
}

State get_state(Reader& in) {
  State state;
  state.time = in.get<double>();
  state.step = in.get<std::int64_t>();
  state.position = in.vec3_array("state.position");
  state.orientation.resize(in.length(32, "state.orientation"));
  for (Quat& q : state.orientation) q = in.quat();
  state.velocity = in.vec3_array("state.velocity");
  state.angular_velocity = in.vec3_array("state.angular_velocity");
  const std::size_t n = state.position.size();
  if (state.orientation.size() != n || state.velocity.size() != n || state.angular_velocity.size() != n) {
    in.fail("state arrays of different lengths");
  }
  return state;
}

/// Every field of a contact: a resumed step must see last step's contacts exactly as the
/// uninterrupted run did (the warm start reads id, frame and impulse; snapshots read the rest).
template <typename Sink>
void put_contact(Writer<Sink>& out, const Contact& c) {
  out.put(c.id.body_a);
  out.put(c.id.body_b);
  out.put(c.id.feature_a);
  out.put(c.id.feature_b);
  out.put(c.point);
  out.put(c.frame);
  out.put(c.gap);
  out.put(c.arm_a);
  out.put(c.arm_b);
  out.put(c.delassus);
  out.put(c.friction_coefficient);
  out.put(c.normal_restitution);
  out.put(c.normal_velocity_before);
  out.put(c.normal_velocity_target);
  out.put(c.impulse);
  out.put(static_cast<std::uint8_t>(c.status));
}
constexpr std::size_t contact_bytes = 4 * 4 + 8 * (3 + 9 + 1 + 3 + 3 + 9 + 4 + 3) + 1;

Contact get_contact(Reader& in) {
  Contact c;
  c.id.body_a = in.get<std::uint32_t>();
  c.id.body_b = in.get<std::uint32_t>();
  c.id.feature_a = in.get<std::uint32_t>();
  c.id.feature_b = in.get<std::uint32_t>();
  c.point = in.vec3();
  c.frame = in.mat3();
  c.gap = in.get<double>();
  c.arm_a = in.vec3();
  c.arm_b = in.vec3();
  c.delassus = in.mat3();
  c.friction_coefficient = in.get<double>();
  c.normal_restitution = in.get<double>();
  c.normal_velocity_before = in.get<double>();
  c.normal_velocity_target = in.get<double>();
  c.impulse = in.vec3();
  const auto status = in.get<std::uint8_t>();
  if (status > static_cast<std::uint8_t>(ContactStatus::sliding)) in.fail(fmt::format("contact status {}", status));
  c.status = static_cast<ContactStatus>(status);
  return c;
}

template <typename Sink>
void put_progress(Writer<Sink>& out, const RunProgress& p) {
  out.put(p.first_step);
  out.put(p.first_time);
  out.put(p.end_step);
  out.put(p.snapshot_period);
  out.put(p.series_rows);
  out.put(p.snapshots);
  out.put(p.iteration_sum);
  out.put(p.max_residual);
  out.put(p.unconverged_steps);
  out.put(p.wall_seconds);
}

RunProgress get_progress(Reader& in) {
  RunProgress p;
  p.first_step = in.get<std::int64_t>();
  p.first_time = in.get<double>();
  p.end_step = in.get<std::int64_t>();
  p.snapshot_period = in.get<std::int64_t>();
  p.series_rows = in.get<std::int64_t>();
  p.snapshots = in.get<std::int64_t>();
  p.iteration_sum = in.get<double>();
  p.max_residual = in.get<double>();
  p.unconverged_steps = in.get<std::int64_t>();
  p.wall_seconds = in.get<double>();
  if (p.snapshot_period < 1 || p.end_step < p.first_step || p.series_rows < 0 || p.snapshots < 0) {
    in.fail("inconsistent run progress (snapshot period, end step, rows)");
  }
  return p;
}

[[noreturn]] void io_error(const fs::path& path, const std::string& what) {
  throw std::runtime_error(fmt::format("{}: {}: {}", path.string(), what, std::strerror(errno)));
}

/// Every byte of the payload, in file order (docs/checkpoints.md). The same function feeds the
/// counter, the in-memory buffer and the file, so the three can never disagree.
template <typename Sink>
void put_payload(Writer<Sink>& out, const CheckpointView& checkpoint) {
  out.put(checkpoint.scene_text);
  out.put(checkpoint.scene_source);
  out.put(checkpoint.end_time);
  out.put(checkpoint.seed);
  put_state(out, checkpoint.state);
  out.put(static_cast<std::uint64_t>(checkpoint.contacts.size()));
  for (const Contact& c : checkpoint.contacts) put_contact(out, c);
  const DetectionMemory& memory = checkpoint.detection_memory;
  out.put(static_cast<std::uint64_t>(memory.pairs.size()));
  for (std::size_t k = 0; k < memory.pairs.size(); ++k) {
    out.put(memory.pairs[k].body_a);
    out.put(memory.pairs[k].body_b);
    out.put(k < memory.common_normals.size() ? memory.common_normals[k] : Vec3::Zero());
  }
  put_progress(out, checkpoint.progress);
  const RestWatch& rest = checkpoint.rest;
  out.put(static_cast<std::uint8_t>(rest.armed));
  out.put(static_cast<std::uint8_t>(rest.window_open));
  out.put(rest.window_start);
  out.put(rest.reference_coordination);
  out.put(static_cast<std::uint64_t>(rest.reference_pairs.size()));
  for (const auto& [a, b] : rest.reference_pairs) {
    out.put(a);
    out.put(b);
  }
  out.put(rest.last_failure);
  out.put(rest.last_speed);
  out.put(rest.last_coordination_change);
  out.put(rest.last_contact_change);
  out.put(rest.decay_window);
  out.put(static_cast<std::uint64_t>(checkpoint.rest.history.size()));
  for (const auto& [t, log_energy] : checkpoint.rest.history) {
    out.put(t);
    out.put(log_energy);
  }
  out.put(checkpoint.held_gravity_step);
  out.put(static_cast<std::uint64_t>(checkpoint.held_gravity.size()));
  for (const Vec3& a : checkpoint.held_gravity) out.put(a);
}

/// The payload size, found by a counting pass (no allocation): the header announces it and the
/// header is covered by the CRC, so it must be known before the first byte is written.
std::uint64_t payload_size(const CheckpointView& checkpoint) {
  ByteCounter counter;
  Writer out(counter);
  put_payload(out, checkpoint);
  return counter.count;
}

template <typename Sink>
void put_header(Writer<Sink>& out, std::uint64_t payload_bytes) {
  for (char c : magic) out.put(c);
  out.put(checkpoint_format_version);
  out.put(std::uint32_t{0});
  out.put(payload_bytes);
}

/// Streams bytes to a new file through a fixed 1 MiB buffer, keeping the CRC-64 of everything
/// written so far: a checkpoint then costs 1 MiB of memory instead of a copy of its payload (the
/// payload is ~300 bytes a contact, hundreds of MB for 10^5 grains). Closes the file if
/// destroyed before finish() (an exception on the way).
class FileSink {
 public:
  explicit FileSink(const fs::path& path) : path_(path), buffer_(std::size_t{1} << 20) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) io_error(path, "cannot create the checkpoint file");
  }
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;
  ~FileSink() {
    if (fd_ >= 0) ::close(fd_);
  }
  void append(const std::byte* p, std::size_t n) {
    while (n > 0) {
      const std::size_t room = std::min(n, buffer_.size() - used_);
      std::memcpy(buffer_.data() + used_, p, room);
      used_ += room;
      p += room;
      n -= room;
      if (used_ == buffer_.size()) flush();
    }
  }
  /// Writes what is buffered, then the CRC-64 of every byte written (not covered by itself), and
  /// fsyncs and closes the file, so that after the rename the data are on disk before the name is.
  void finish() {
    flush();
    const std::uint64_t crc = crc_;
    write_all(reinterpret_cast<const std::byte*>(&crc), sizeof crc);
    const int fd = std::exchange(fd_, -1);
    if (::fsync(fd) != 0) {
      const int saved = errno;
      ::close(fd);
      errno = saved;
      io_error(path_, "cannot fsync the checkpoint file");
    }
    if (::close(fd) != 0) io_error(path_, "cannot close the checkpoint file");
  }

 private:
  void flush() {
    crc_ = crc64(std::span<const std::byte>(buffer_.data(), used_), crc_);
    write_all(buffer_.data(), used_);
    used_ = 0;
  }
  void write_all(const std::byte* p, std::size_t n) {
    std::size_t written = 0;
    while (written < n) {
      const ssize_t k = ::write(fd_, p + written, n - written);
      if (k < 0) {
        if (errno == EINTR) continue;
        io_error(path_, "cannot write the checkpoint file");
      }
      written += static_cast<std::size_t>(k);
    }
  }
  const fs::path& path_;
  std::vector<std::byte> buffer_;
  std::size_t used_ = 0;
  std::uint64_t crc_ = 0;
  int fd_ = -1;
};

/// fsync of a folder makes a rename inside it durable (POSIX leaves it otherwise unspecified).
void sync_folder(const fs::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) io_error(folder, "cannot open the checkpoint folder");
  const int status = ::fsync(fd);
  ::close(fd);
  if (status != 0 && errno != EINVAL) io_error(folder, "cannot fsync the checkpoint folder");
}

bool is_checkpoint_name(const std::string& name) {
  return name.size() == 5 + 12 + 5 && name.starts_with("step-") && name.ends_with(".ckpt") &&
         std::all_of(name.begin() + 5, name.begin() + 17, [](char c) { return c >= '0' && c <= '9'; });
}

}  // namespace

std::uint64_t crc64(std::span<const std::byte> bytes, std::uint64_t crc) {
  crc = ~crc;
  for (std::byte b : bytes) crc = crc_table[(crc ^ static_cast<std::uint8_t>(b)) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

std::uint64_t state_hash(const State& state) {
  CrcSink crc;
  {
    Writer out(crc);
    put_state(out, state);
  }
  crc.flush();
  return crc.crc;
}

CheckpointView checkpoint_view(const Checkpoint& checkpoint) {
  return CheckpointView{checkpoint.scene_text,       checkpoint.scene_source, checkpoint.end_time,
                        checkpoint.seed,             checkpoint.state,        checkpoint.contacts,
                        checkpoint.detection_memory, checkpoint.progress,     checkpoint.rest,
                        checkpoint.held_gravity,     checkpoint.held_gravity_step};
}

std::vector<std::byte> serialize_checkpoint(const CheckpointView& checkpoint) {
  const std::uint64_t payload_bytes = payload_size(checkpoint);
  ByteBuffer buffer;
  buffer.bytes.reserve(header_bytes + static_cast<std::size_t>(payload_bytes) + trailer_bytes);
  Writer out(buffer);
  put_header(out, payload_bytes);
  put_payload(out, checkpoint);
  out.put(crc64(buffer.bytes));
  return std::move(buffer.bytes);
}

std::vector<std::byte> serialize_checkpoint(const Checkpoint& checkpoint) {
  return serialize_checkpoint(checkpoint_view(checkpoint));
}

void write_checkpoint_file(const fs::path& file, const CheckpointView& checkpoint) {
  const std::uint64_t payload_bytes = payload_size(checkpoint);
  FileSink sink(file);
  Writer out(sink);
  put_header(out, payload_bytes);
  put_payload(out, checkpoint);
  sink.finish();
}

Checkpoint deserialize_checkpoint(std::span<const std::byte> bytes, const std::string& source) {
  if (bytes.size() < header_bytes + trailer_bytes) {
    throw CheckpointError(fmt::format("{}: truncated checkpoint ({} bytes, a header alone takes {})", source,
                                      bytes.size(), header_bytes + trailer_bytes));
  }
  if (std::memcmp(bytes.data(), magic.data(), magic.size()) != 0) {
    throw CheckpointError(source + ": not a rubble checkpoint (bad magic bytes)");
  }
  Reader header(bytes.subspan(0, header_bytes), source);
  for (std::size_t i = 0; i < magic.size(); ++i) header.get<char>();
  const auto version = header.get<std::uint32_t>();
  header.get<std::uint32_t>();
  const auto payload_size = header.get<std::uint64_t>();
  if (version != checkpoint_format_version) {
    throw CheckpointError(fmt::format(
        "{}: checkpoint format version {}, this rubble reads version {}{}", source, version, checkpoint_format_version,
        version < checkpoint_format_version
            ? " (written by an older rubble: finish that run with it, or start a new run from its state with "
              "rubble run SCENE --from RUN_DIR:snapshot=K, docs/checkpoints.md)"
            : ""));
  }
  if (payload_size != bytes.size() - header_bytes - trailer_bytes) {
    throw CheckpointError(fmt::format("{}: truncated or extended checkpoint: the header announces {} payload bytes, "
                                      "the file holds {}",
                                      source, payload_size, bytes.size() - header_bytes - trailer_bytes));
  }
  std::uint64_t stored_crc = 0;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - trailer_bytes, trailer_bytes);
  const std::uint64_t crc = crc64(bytes.subspan(0, bytes.size() - trailer_bytes));
  if (crc != stored_crc) {
    throw CheckpointError(fmt::format("{}: checksum mismatch (stored {:016x}, computed {:016x}): the file is damaged",
                                      source, stored_crc, crc));
  }

  Reader in(bytes.subspan(header_bytes, static_cast<std::size_t>(payload_size)), source);
  Checkpoint checkpoint;
  checkpoint.scene_text = in.text();
  checkpoint.scene_source = in.text();
  checkpoint.end_time = in.get<double>();
  checkpoint.seed = in.get<std::uint64_t>();
  checkpoint.state = get_state(in);
  const std::size_t n = checkpoint.state.body_count();
  checkpoint.contacts.resize(in.length(contact_bytes, "contacts"));
  for (Contact& c : checkpoint.contacts) {
    c = get_contact(in);
    if (c.id.body_a >= n || c.id.body_b >= n) in.fail("contact body id out of range");
  }
  const std::size_t pairs = in.length(4 + 4 + 24, "detection memory");
  checkpoint.detection_memory.pairs.resize(pairs);
  checkpoint.detection_memory.common_normals.resize(pairs);
  for (std::size_t k = 0; k < pairs; ++k) {
    checkpoint.detection_memory.pairs[k].body_a = in.get<std::uint32_t>();
    checkpoint.detection_memory.pairs[k].body_b = in.get<std::uint32_t>();
    checkpoint.detection_memory.common_normals[k] = in.vec3();
  }
  checkpoint.progress = get_progress(in);
  RestWatch& rest = checkpoint.rest;
  rest.armed = in.get<std::uint8_t>() != 0;
  rest.window_open = in.get<std::uint8_t>() != 0;
  rest.window_start = in.get<double>();
  rest.reference_coordination = in.get<double>();
  rest.reference_pairs.resize(in.length(8, "rest reference contacts"));
  for (auto& [a, b] : rest.reference_pairs) {
    a = in.get<std::uint32_t>();
    b = in.get<std::uint32_t>();
    if (a >= n || b >= n) in.fail(fmt::format("rest reference contact ({}, {}) out of the {} bodies", a, b, n));
  }
  rest.last_failure = in.get<std::uint8_t>();
  if (rest.last_failure > 3) in.fail(fmt::format("rest condition {} unknown", rest.last_failure));
  rest.last_speed = in.get<double>();
  rest.last_coordination_change = in.get<double>();
  rest.last_contact_change = in.get<double>();
  rest.decay_window = in.get<double>();
  checkpoint.rest.history.resize(in.length(16, "rest history"));
  for (auto& [t, log_energy] : checkpoint.rest.history) {
    t = in.get<double>();
    log_energy = in.get<double>();
  }
  checkpoint.held_gravity_step = in.get<std::int64_t>();
  checkpoint.held_gravity.resize(in.length(24, "held gravity"));
  for (Vec3& a : checkpoint.held_gravity) a = in.vec3();
  if (!checkpoint.held_gravity.empty() && checkpoint.held_gravity.size() != n) {
    in.fail(fmt::format("held gravity field of {} bodies, the state has {}", checkpoint.held_gravity.size(), n));
  }
  if (!in.at_end()) in.fail("unexpected bytes after the payload");
  if (checkpoint.state.step < checkpoint.progress.first_step || checkpoint.state.step > checkpoint.progress.end_step) {
    in.fail(fmt::format("step {} outside the run's steps [{}, {}]", checkpoint.state.step,
                        checkpoint.progress.first_step, checkpoint.progress.end_step));
  }
  return checkpoint;
}

fs::path checkpoint_folder(const fs::path& output_directory) { return output_directory / "checkpoints"; }

fs::path write_checkpoint(const fs::path& folder, const Checkpoint& checkpoint, int keep, std::int64_t keep_every) {
  return write_checkpoint(folder, checkpoint_view(checkpoint), keep, keep_every);
}

std::int64_t checkpoint_step(const fs::path& file) {
  const std::string name = file.filename().string();
  if (!is_checkpoint_name(name)) return -1;
  return std::stoll(name.substr(5, 12));
}

std::vector<fs::path> set_aside_checkpoints_after(const fs::path& folder, std::int64_t step) {
  std::vector<fs::path> moved;
  for (const fs::path& file : list_checkpoints(folder)) {
    if (checkpoint_step(file) <= step) continue;
    fs::path aside = file;
    aside += ".superseded";
    std::error_code error;
    fs::rename(file, aside, error);
    if (!error) moved.push_back(aside);
  }
  return moved;
}

fs::path write_checkpoint(const fs::path& folder, const CheckpointView& checkpoint, int keep, std::int64_t keep_every) {
  keep = std::max(keep, 1);
  fs::create_directories(folder);
  const std::string name = fmt::format("step-{:012}.ckpt", checkpoint.state.step);
  const fs::path final_path = folder / name;
  const fs::path temporary = folder / (name + ".tmp");
  try {
    write_checkpoint_file(temporary, checkpoint);
  } catch (...) {
    // A partial temporary (disk full, I/O error) is never read; removing it gives its space back.
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw;
  }
  if (::rename(temporary.c_str(), final_path.c_str()) != 0) io_error(final_path, "cannot rename the checkpoint into place");
  sync_folder(folder);

  // Only now, with the new checkpoint durable, drop the old ones (and stray temporaries).
  // Newest first: the newest `keep` stay; of the older ones, with keep_every > 0, the first
  // (lowest step) of each interval of keep_every steps stays too.
  const std::vector<fs::path> all = list_checkpoints(folder);
  for (std::size_t k = static_cast<std::size_t>(keep); k < all.size(); ++k) {
    if (keep_every > 0) {
      const std::int64_t interval = checkpoint_step(all[k]) / keep_every;
      const bool first_of_interval = k + 1 == all.size() || checkpoint_step(all[k + 1]) / keep_every != interval;
      if (first_of_interval) continue;
    }
    std::error_code ignored;
    fs::remove(all[k], ignored);
  }
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string file = entry.path().filename().string();
    if (file.ends_with(".ckpt.tmp")) {
      std::error_code ignored;
      fs::remove(entry.path(), ignored);
    }
  }
  return final_path;
}

Checkpoint read_checkpoint(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw CheckpointError(file.string() + ": cannot open the checkpoint file");
  // Read at the file's size in one go (growing a vector byte by byte would take twice the memory).
  std::error_code error;
  const std::uintmax_t size = fs::file_size(file, error);
  if (error) throw CheckpointError(file.string() + ": cannot read the checkpoint file: " + error.message());
  std::vector<char> raw(static_cast<std::size_t>(size));
  in.read(raw.data(), static_cast<std::streamsize>(raw.size()));
  if (in.gcount() != static_cast<std::streamsize>(raw.size())) {
    throw CheckpointError(file.string() + ": cannot read the checkpoint file (it changed size while being read)");
  }
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(raw.data()), raw.size());
  return deserialize_checkpoint(bytes, file.string());
}

std::vector<fs::path> list_checkpoints(const fs::path& folder) {
  std::vector<fs::path> files;
  std::error_code error;
  if (!fs::is_directory(folder, error)) return files;
  for (const auto& entry : fs::directory_iterator(folder, error)) {
    if (is_checkpoint_name(entry.path().filename().string())) files.push_back(entry.path());
  }
  // Zero-padded step numbers: names sort by step.
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) { return a.filename() > b.filename(); });
  return files;
}

LoadedCheckpoint load_newest_checkpoint(const fs::path& folder) {
  LoadedCheckpoint loaded;
  for (const fs::path& file : list_checkpoints(folder)) {
    try {
      loaded.checkpoint = read_checkpoint(file);
      loaded.file = file;
      return loaded;
    } catch (const CheckpointError& error) {
      loaded.rejected.emplace_back(error.what());
    }
  }
  std::string message = folder.string() + ": no usable checkpoint";
  if (loaded.rejected.empty()) message += " (no step-*.ckpt file)";
  for (const std::string& reason : loaded.rejected) message += "\n  rejected " + reason;
  throw CheckpointError(message);
}

RestWatch save_rest_watch(const RestDetector& detector) {
  RestWatch watch;
  watch.armed = detector.armed;
  watch.window_open = detector.window_start.has_value();
  watch.window_start = detector.window_start.value_or(0.0);
  watch.reference_coordination = detector.reference_coordination;
  watch.reference_pairs = detector.reference_pairs;
  watch.last_failure = static_cast<std::uint8_t>(detector.last_failure);
  watch.last_speed = detector.last_speed;
  watch.last_coordination_change = detector.last_coordination_change;
  watch.last_contact_change = detector.last_contact_change;
  watch.history.assign(detector.history.begin(), detector.history.end());
  watch.decay_window = detector.decay_window;
  return watch;
}

void restore_rest_watch(const RestWatch& watch, RestDetector& detector) {
  detector.armed = watch.armed;
  detector.window_start.reset();
  if (watch.window_open) detector.window_start = watch.window_start;
  detector.reference_coordination = watch.reference_coordination;
  detector.reference_pairs = watch.reference_pairs;
  detector.last_failure = static_cast<RestCondition>(watch.last_failure);
  detector.last_speed = watch.last_speed;
  detector.last_coordination_change = watch.last_coordination_change;
  detector.last_contact_change = watch.last_contact_change;
  detector.history.assign(watch.history.begin(), watch.history.end());
  detector.decay_window = watch.decay_window;
}

}  // namespace rubble
