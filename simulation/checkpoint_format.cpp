// Checkpoint bytes: CRC-64, the in-memory serialisation, the parser with its checks, and the state
// hash (checkpoint.hpp). The payload's layout is written by checkpoint_codec.hpp's put_payload and
// read back here field by field in the same order.
#include <algorithm>
#include <array>
#include <cstring>
#include <fmt/format.h>
#include <utility>

#include "simulation/checkpoint.hpp"
#include "simulation/checkpoint_codec.hpp"

namespace rubble {
namespace {

using namespace checkpoint_codec;

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

/// Appends to a buffer (serialize_checkpoint).
struct ByteBuffer {
  void append(const std::byte* p, std::size_t n) { bytes.insert(bytes.end(), p, p + n); }
  std::vector<std::byte> bytes;  ///< everything appended
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

/// Reads values back, checking every read against the end of the payload.
class Reader {
 public:
  Reader(std::span<const std::byte> bytes, const std::string& source) : bytes_(bytes), source_(source) {}

  template <typename T>
  requires std::is_arithmetic_v<T> T get() {
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
  c.angular_impulse = in.vec3();
  const auto status = in.get<std::uint8_t>();
  if (status > static_cast<std::uint8_t>(ContactStatus::sliding)) in.fail(fmt::format("contact status {}", status));
  c.status = static_cast<ContactStatus>(status);
  return c;
}

/// The carry's contacts and detection memory (put_contacts_and_memory); `n` bodies.
void get_contacts_and_memory(Reader& in, std::size_t n, StepCarry& carry) {
  carry.contacts.resize(in.length(contact_bytes, "contacts"));
  for (Contact& c : carry.contacts) {
    c = get_contact(in);
    if (c.id.body_a >= n || c.id.body_b >= n) in.fail("contact body id out of range");
  }
  const std::size_t pairs = in.length(4 + 4 + 24, "detection memory");
  carry.detection_memory.pairs.resize(pairs);
  carry.detection_memory.common_normals.resize(pairs);
  for (std::size_t k = 0; k < pairs; ++k) {
    carry.detection_memory.pairs[k].body_a = in.get<std::uint32_t>();
    carry.detection_memory.pairs[k].body_b = in.get<std::uint32_t>();
    carry.detection_memory.common_normals[k] = in.vec3();
  }
}

/// The carry's held self-gravity field (put_held_gravity); `n` bodies.
void get_held_gravity(Reader& in, std::size_t n, StepCarry& carry) {
  carry.held_gravity_step = in.get<std::int64_t>();
  carry.held_gravity.resize(in.length(24, "held gravity"));
  for (Vec3& a : carry.held_gravity) a = in.vec3();
  if (!carry.held_gravity.empty() && carry.held_gravity.size() != n) {
    in.fail(fmt::format("held gravity field of {} bodies, the state has {}", carry.held_gravity.size(), n));
  }
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

/// The rest watcher's memory (put_rest); `n` bodies.
RestWatch get_rest(Reader& in, std::size_t n) {
  RestWatch rest;
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
  rest.history.resize(in.length(16, "rest history"));
  for (auto& [t, log_energy] : rest.history) {
    t = in.get<double>();
    log_energy = in.get<double>();
  }
  return rest;
}

/// Checks the header and the CRC of file bytes; returns the payload's size.
std::uint64_t check_frame(std::span<const std::byte> bytes, const std::string& source) {
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
    throw CheckpointError(
        fmt::format("{}: truncated or extended checkpoint: the header announces {} payload bytes, "
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
  return payload_size;
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
  return CheckpointView{checkpoint.scene_text, checkpoint.scene_source, checkpoint.end_time, checkpoint.seed,
                        checkpoint.state,      checkpoint.carry,        checkpoint.progress, checkpoint.rest};
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

Checkpoint deserialize_checkpoint(std::span<const std::byte> bytes, const std::string& source) {
  const std::uint64_t payload_size = check_frame(bytes, source);
  // Field by field in put_payload's order.
  Reader in(bytes.subspan(header_bytes, static_cast<std::size_t>(payload_size)), source);
  Checkpoint checkpoint;
  checkpoint.scene_text = in.text();
  checkpoint.scene_source = in.text();
  checkpoint.end_time = in.get<double>();
  checkpoint.seed = in.get<std::uint64_t>();
  checkpoint.state = get_state(in);
  const std::size_t n = checkpoint.state.body_count();
  get_contacts_and_memory(in, n, checkpoint.carry);
  checkpoint.progress = get_progress(in);
  checkpoint.rest = get_rest(in, n);
  get_held_gravity(in, n, checkpoint.carry);
  if (!in.at_end()) in.fail("unexpected bytes after the payload");
  if (checkpoint.state.step < checkpoint.progress.first_step || checkpoint.state.step > checkpoint.progress.end_step) {
    in.fail(fmt::format("step {} outside the run's steps [{}, {}]", checkpoint.state.step,
                        checkpoint.progress.first_step, checkpoint.progress.end_step));
  }
  return checkpoint;
}

}  // namespace rubble
