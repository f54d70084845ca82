#pragma once
// Contact detection, stages 3 and 4 of the step: broad phase (which pairs may touch), narrow
// phase (contact points, frames and gaps of each pair), then carrying last step's impulses to the
// contacts that persist (warm start).
#include <cstdint>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

struct PolyhedronScratch;  // narrow_phase_polyhedra.hpp

/// Settings of contact detection.
struct DetectionOptions {
  /// m: pairs whose gap is below this distance produce contact points, so that contacts about
  /// to close within the step are known to the solver (LMGC90's alert distance). Zero picks
  /// 5% of the smallest grain radius.
  double alert_distance = 0.0;
  /// m: the broad phase runs with the alert distance plus this margin, and its pairs are reused
  /// until some body has moved by more than half the margin since (a Verlet list): no pair can
  /// have come within the alert distance unseen, so the contacts are exactly those of a broad
  /// phase every step. Negative: automatic (the alert distance); 0: a broad phase every step.
  double pair_list_margin = -1.0;
};

/// A candidate pair from the broad phase, body_a < body_b.
struct BodyPair {
  std::uint32_t body_a = 0;  ///< lower body id
  std::uint32_t body_b = 0;  ///< higher body id
  auto operator<=>(const BodyPair&) const = default;
};

/// What one detection call did, for the step's report.
struct DetectionStats {
  std::size_t candidate_pairs = 0;  ///< pairs passed to the narrow phase
  bool pair_list_rebuilt = false;   ///< the broad phase ran this step (else last list reused)
  double broad_phase_seconds = 0;   ///< wall time of the broad phase
  double narrow_phase_seconds = 0;  ///< wall time of the narrow phase
};

/// Remembered between steps for persistent pairs: the common-plane normal of polyhedron pairs
/// (warm start of the common-plane iteration). Sorted by pair; part of what a checkpoint saves.
struct DetectionMemory {
  std::vector<BodyPair> pairs;       ///< sorted
  std::vector<Vec3> common_normals;  ///< world frame, one per pair
  /// The broad phase's pairs within alert distance + margin (DetectionOptions::pair_list_margin),
  /// and every body's position when they were found. Not saved in checkpoints: an empty list is
  /// rebuilt, and a list from any earlier step gives the same contacts.
  std::vector<BodyPair> pair_list;
  std::vector<Vec3> pair_list_positions;  ///< m, per body, at the list's broad phase
  double pair_list_margin = 0.0;          ///< m, the margin the list was built with
  /// Indices into pair_list in the order of their contacts' ids (collide_pair puts a wall first,
  /// so a wall numbered after the grains is its contacts' body_a): visiting the pairs in this
  /// order yields a sorted contact list without sorting the contacts.
  std::vector<std::uint32_t> pair_order;
  /// Contact points the last detection found: the next list's reserved size (an estimate only;
  /// not saved in checkpoints, 0 after a resume).
  std::size_t contact_count = 0;
  /// The remembered normal for a pair, or nullptr.
  const Vec3* find(const BodyPair& pair) const;
};

/// The alert distance actually used: options.alert_distance, or 5% of the smallest grain radius.
double resolve_alert_distance(const Model& model, const DetectionOptions& options);

/// Broad phase: every pair of bodies whose bounding volumes, inflated by the alert distance,
/// overlap. Grains are binned in a uniform grid (cell size from the 90th-percentile grain size, large
/// grains span several cells, each pair reported once by the cell owning the lower corner of the
/// overlap of the two boxes), so the cost is O(N) for bounded size ratios; walls are tested
/// against every grain. Sorted, so the result does not depend on the thread count.
std::vector<BodyPair> find_candidate_pairs(const Model& model, const State& state, double alert_distance);

/// Narrow phase for one pair: appends the pair's contact points with gap < alert_distance.
/// `memory` is last step's detection memory (read) and `common_normal` receives this step's
/// common-plane normal for polyhedron pairs (unchanged otherwise).
/// `scratch` is the polyhedral narrow phase's working space (one per thread, reused from pair to pair).
void collide_pair(const Model& model, const State& state, const BodyPair& pair, double alert_distance,
                  const DetectionMemory& memory, ContactList& contacts, Vec3& common_normal,
                  PolyhedronScratch& scratch);
/// The same with a scratch of its own (allocates; for tests and one-off calls).
void collide_pair(const Model& model, const State& state, const BodyPair& pair, double alert_distance,
                  const DetectionMemory& memory, ContactList& contacts, Vec3& common_normal);

/// Stage 3 of the step: all contact points of the scene, sorted by id. Updates `memory`.
ContactList detect_contacts(const Model& model, const State& state, const DetectionOptions& options,
                            DetectionMemory& memory, DetectionStats* stats = nullptr);

/// What warm start needs of one of last step's contacts: its identity and its impulse in the world
/// frame (frame * local impulse). 40 bytes instead of a whole Contact, so that last step's list can
/// be freed before this step's is built (at 10^5 spheres the two lists alive at once were the
/// run's peak memory).
struct CarriedImpulse {
  ContactId id;        ///< identity of last step's contact
  Vec3 world_impulse;  ///< N s, impulse on body b in the world frame
};

/// Last step's contacts reduced to what carry_impulses needs, in the same (id) order.
std::vector<CarriedImpulse> impulses_to_carry(const ContactList& previous);

/// Stage 4 of the step (match_contacts): for each contact whose id was present last step, starts
/// from last step's impulse, rotated from the old local frame to the new one. Both lists sorted.
void carry_impulses(const std::vector<CarriedImpulse>& previous, ContactList& current);

/// The same from last step's full contact list (carry_impulses(impulses_to_carry(previous), current)).
void carry_impulses(const ContactList& previous, ContactList& current);

/// Last step's angular impulses (Contact::angular_impulse: rolling and twisting resistance) in the
/// world frame, one per contact of `previous`, in its order (index-aligned with impulses_to_carry's
/// records). Only built when some contact law resists rotation, so that plain scenes carry 40 bytes
/// a point as before.
std::vector<Vec3> angular_impulses_to_carry(const ContactList& previous);

/// Stage 4 for the angular impulses: each contact whose id was present last step starts from last
/// step's angular impulse, rotated into the new frame (the matching of carry_impulses; `previous`
/// gives the ids, `previous_angular` the impulses, index-aligned with it).
void carry_angular_impulses(const std::vector<CarriedImpulse>& previous, const std::vector<Vec3>& previous_angular,
                            ContactList& current);

}  // namespace rubble
