#pragma once
// The checkpoint payload's byte layout, written by one template for every destination: a byte
// counter (the payload size the header announces), an in-memory buffer (serialize_checkpoint)
// and the streamed file (write_checkpoint). Internal to simulation/checkpoint*.cpp; the format is
// described in checkpoint.hpp and docs/checkpoints.md.
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "simulation/checkpoint.hpp"

namespace rubble::checkpoint_codec {

static_assert(std::endian::native == std::endian::little, "checkpoints are written little-endian");

inline constexpr std::array<char, 8> magic{'R', 'U', 'B', 'B', 'L', 'E', 'C', 'K'};
inline constexpr std::size_t header_bytes = 8 + 4 + 4 + 8;  // magic, version, reserved, payload size
inline constexpr std::size_t trailer_bytes = 8;             // CRC-64
/// Bytes of one contact in the payload (put_contact).
inline constexpr std::size_t contact_bytes = 4 * 4 + 8 * (3 + 9 + 1 + 3 + 3 + 9 + 4 + 3 + 3) + 1;

/// Only counts the bytes (the payload size announced in the header before the payload is streamed).
struct ByteCounter {
  void append(const std::byte*, std::size_t n) { count += n; }
  std::uint64_t count = 0;  ///< bytes appended
};

/// Writes values in native (little-endian) order to a sink with append(const std::byte*, size_t).
template <typename Sink>
class Writer {
 public:
  explicit Writer(Sink& sink) : sink_(sink) {}
  template <typename T>
  requires std::is_arithmetic_v<T>
  void put(T value) { sink_.append(reinterpret_cast<const std::byte*>(&value), sizeof(T)); }
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

template <typename Sink>
void put_state(Writer<Sink>& out, const State& state) {
  out.put(state.time);
  out.put(state.step);
  out.put_array(state.position);
  out.put_array(state.orientation);
  out.put_array(state.velocity);
  out.put_array(state.angular_velocity);
}

/// Every field of a contact: a resumed step must see last step's contacts exactly as the
/// uninterrupted run did (the warm start reads id, frame, impulse and angular impulse; snapshots
/// read the rest). The angular impulse (rolling and twisting resistance) since format version 4.
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
  out.put(c.angular_impulse);
  out.put(static_cast<std::uint8_t>(c.status));
}

/// The carry's contacts and detection memory (pairs and their common normals).
template <typename Sink>
void put_contacts_and_memory(Writer<Sink>& out, const StepCarry& carry) {
  out.put(static_cast<std::uint64_t>(carry.contacts.size()));
  for (const Contact& c : carry.contacts) put_contact(out, c);
  const DetectionMemory& memory = carry.detection_memory;
  out.put(static_cast<std::uint64_t>(memory.pairs.size()));
  for (std::size_t k = 0; k < memory.pairs.size(); ++k) {
    out.put(memory.pairs[k].body_a);
    out.put(memory.pairs[k].body_b);
    out.put(k < memory.common_normals.size() ? memory.common_normals[k] : Vec3::Zero());
  }
}

/// The carry's held self-gravity field: its step, then the accelerations.
template <typename Sink>
void put_held_gravity(Writer<Sink>& out, const StepCarry& carry) {
  out.put(carry.held_gravity_step);
  out.put(static_cast<std::uint64_t>(carry.held_gravity.size()));
  for (const Vec3& a : carry.held_gravity) out.put(a);
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

template <typename Sink>
void put_rest(Writer<Sink>& out, const RestWatch& rest) {
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
  out.put(static_cast<std::uint64_t>(rest.history.size()));
  for (const auto& [t, log_energy] : rest.history) {
    out.put(t);
    out.put(log_energy);
  }
}

/// Every byte of the payload, in file order (docs/checkpoints.md). The same function feeds the
/// counter, the in-memory buffer and the file, so the three can never disagree. The held gravity
/// field comes last, after the run's bookkeeping, not beside the rest of the StepCarry: it was
/// added at the end of the payload in format version 2, and this order keeps the layout of version 3
/// (version 4 added a field to every contact).
template <typename Sink>
void put_payload(Writer<Sink>& out, const CheckpointView& checkpoint) {
  out.put(checkpoint.scene_text);
  out.put(checkpoint.scene_source);
  out.put(checkpoint.end_time);
  out.put(checkpoint.seed);
  put_state(out, checkpoint.state);
  put_contacts_and_memory(out, checkpoint.carry);
  put_progress(out, checkpoint.progress);
  put_rest(out, checkpoint.rest);
  put_held_gravity(out, checkpoint.carry);
}

/// The payload size, found by a counting pass (no allocation): the header announces it and the
/// header is covered by the CRC, so it must be known before the first byte is written.
inline std::uint64_t payload_size(const CheckpointView& checkpoint) {
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

}  // namespace rubble::checkpoint_codec
