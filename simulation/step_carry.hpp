#pragma once
// What one time step hands to the next besides the State: the data a run must keep between steps
// (and a checkpoint must save) for the next step to be the one an uninterrupted run takes. The
// step's scratch arrays (forces, free velocities, StepWorkspace in step.hpp) are rebuilt every
// step and are not part of it.
//
// Restart = Model (rebuilt from the scene text) + State (core/state.hpp) + StepCarry + the run
// loop's bookkeeping (simulation/checkpoint.hpp: RunProgress, RestWatch). LMGC90 keeps the same
// split: the bodies' state files (DOF.OUT) and the contacts' last reactions (Vloc_Rloc.OUT, read
// back for warm start), the latter written by its StockRloc stage (Dubois & Jean 2003).
#include <cstdint>
#include <vector>

#include "core/contact.hpp"
#include "contact_detection/detection.hpp"
#include "core/math.hpp"

namespace rubble {

/// Data carried from one step to the next besides the state. A plain struct; a checkpoint saves
/// every field listed here (DetectionMemory: its pairs and normals; its pair list and size
/// estimate are rebuilt and change no result).
struct StepCarry {
  /// Last step's contacts with every field (ids, frames, impulses): the warm start of the next
  /// step's solver, and what snapshots and the rest watcher read after a step.
  ContactList contacts;
  DetectionMemory detection_memory;  ///< common-plane normals of persistent polyhedron pairs
  /// Self-gravity acceleration per body (m/s^2; zero for walls) as last evaluated, reused until
  /// GravitySettings::evaluate_every steps have passed (step.hpp). Empty when evaluate_every = 1.
  std::vector<Vec3> held_gravity;
  /// state.step at which held_gravity was evaluated (-1: never).
  std::int64_t held_gravity_step = -1;
};

}  // namespace rubble
