#pragma once
// A contact point between two bodies: what detection finds (point, frame, gap) and what the
// solver works on (Delassus block, target velocity, impulse). One struct per contact point. In core/
// so that the solver and the post-processing use it without linking detection.
#include <compare>
#include <cstdint>
#include <vector>

#include "core/math.hpp"

namespace rubble {

/// Stable identity of a contact point across steps: the body pair and the features that touch
/// (vertex/edge/face ids for polyhedra, 0 for spheres and planes). Used to carry last step's
/// impulse to this step's contact (warm start).
struct ContactId {
  std::uint32_t body_a = 0;     ///< first body (lower id for grain pairs)
  std::uint32_t body_b = 0;     ///< second body
  std::uint32_t feature_a = 0;  ///< feature of body a
  std::uint32_t feature_b = 0;  ///< feature of body b
  auto operator<=>(const ContactId&) const = default;
};

/// How the solver left a contact at the end of the step.
enum class ContactStatus : std::uint8_t {
  open,      ///< no impulse (separating or not touching)
  sticking,  ///< inside the Coulomb cone
  sliding,   ///< on the cone's boundary
};

/// One contact point. The local frame's first column is the normal n, pointing from body a to
/// body b; local vectors are ordered (normal, t, s). Conventions (docs/architecture.md): the gap is
/// positive when separated, the normal relative velocity U_n = n . (v_b(point) - v_a(point)) is
/// positive when separating, and the impulse r is the impulse on body b over the step (N s);
/// body a receives -r.
struct Contact {
  ContactId id;                   ///< identity for warm start
  Vec3 point = Vec3::Zero();      ///< m, world frame (midway between the surfaces)
  Mat3 frame = Mat3::Identity();  ///< columns n, t, s (world frame)
  double gap = 0.0;               ///< m, signed distance between the surfaces

  // Filled by the solver's preparation.
  Vec3 arm_a = Vec3::Zero();            ///< m, point - centre of mass of a
  Vec3 arm_b = Vec3::Zero();            ///< m, point - centre of mass of b
  Mat3 delassus = Mat3::Zero();         ///< W_aa: local relative velocity per unit local impulse
  double friction_coefficient = 0.0;    ///< mu of the pair's contact law
  double normal_restitution = 0.0;      ///< e_n of the pair's contact law
  double normal_velocity_before = 0.0;  ///< U_n at the start of the step, m/s
  double normal_velocity_target = 0.0;  ///< b: the solver enforces 0 <= r_n _|_ U_n - b >= 0, m/s
  /// c = F_c h / (points of the pair), N s: the pull this point may exert (ContactLaw::cohesion);
  /// the solver enforces 0 <= r_n + c _|_ U_n - b >= 0 and ||r_T|| <= mu (r_n + c). 0 without cohesion.
  double cohesive_impulse = 0.0;

  // The unknown.
  Vec3 impulse = Vec3::Zero();  ///< local impulse (r_n, r_t, r_s), N s (r_n >= -cohesive_impulse)
  /// The rolling and twisting resistance's angular impulse (m_n, m_t, m_s) on body b in the contact
  /// frame, N m s (body a receives -m; ContactLaw::rolling_friction, twisting_friction): warm-started
  /// and checkpointed like `impulse`. Zero for contacts without these laws.
  Vec3 angular_impulse = Vec3::Zero();
  ContactStatus status = ContactStatus::open;  ///< after the solve
};

/// The contact points of one step, in a deterministic order (sorted by id).
using ContactList = std::vector<Contact>;

}  // namespace rubble
