#include "simulation/scene_keys.hpp"

#include <limits>

namespace rubble::scene_detail {

const std::vector<SectionKey<SolverOptions>>& solver_keys() {
  using O = SolverOptions;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "tolerance",
       .option = [](O& o) -> OptionRef { return &o.tolerance; },
       .range = positive(),
       .doc = "stop the sweeps when the residual is below it"},
      {.name = "max_iterations",
       .option = [](O& o) -> OptionRef { return &o.max_iterations; },
       .low = 1,
       .high = 100'000'000,
       .doc = "sweeps at most per step"},
      {.name = "relaxation",
       .option = [](O& o) -> OptionRef { return &o.relaxation; },
       .range = open(0.0, 2.0),
       .doc = "omega: r <- omega r_local + (1 - omega) r_old"},
      {.name = "warm_start",
       .option = [](O& o) -> OptionRef { return &o.warm_start; },
       .doc = "start from last step's impulses of persistent contacts"},
      {.name = "penetration_correction",
       .option = [](O& o) -> OptionRef { return &o.overlap_recovery.fraction; },
       .range = closed(0.0, 1.0),
       .doc = "fraction of the overlap beyond allowed_overlap removed per step"},
      {.name = "max_correction_velocity",
       .option = [](O& o) -> OptionRef { return &o.overlap_recovery.max_velocity; },
       .range = non_negative(),
       .doc = "m/s, cap on a contact's recovery pseudo-velocity"},
      {.name = "allowed_overlap",
       .option = [](O& o) -> OptionRef { return &o.overlap_recovery.allowed_overlap; },
       .range = closed(0.0, 1.0),
       .doc = "overlap left alone, as a fraction of the smaller bounding radius"},
      {.name = "polish_after",
       .option = [](O& o) -> OptionRef { return &o.polish_after; },
       .low = 0,
       .high = 100'000'000,
       .doc = "sweeps without convergence before a Newton polish; 0 = never"},
      {.name = "polish_iterations",
       .option = [](O& o) -> OptionRef { return &o.polish_iterations; },
       .low = 1,
       .high = 10'000,
       .doc = "Newton (Levenberg-Marquardt) steps per polish at most"},
      {.name = "polish_max_contacts",
       .option = [](O& o) -> OptionRef { return &o.polish_max_contacts; },
       .low = 0,
       .high = 100'000'000,
       .doc = "steps with more contacts are not polished"},
      {.name = "polish_attempts_per_step",
       .option = [](O& o) -> OptionRef { return &o.polish_attempts_per_step; },
       .low = 1,
       .high = 100,
       .doc = "Newton polishes per step at most"},
      {.name = "block_count",
       .option = [](O& o) -> OptionRef { return &o.block_count; },
       .low = 1,
       .high = 1'000'000,
       .doc = "spatial blocks of the sweep order (Morton-order ranges swept concurrently)"},
  };
  return keys;
}

const std::vector<SectionKey<DetectionOptions>>& detection_keys() {
  using O = DetectionOptions;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "alert_distance",
       .option = [](O& o) -> OptionRef { return &o.alert_distance; },
       .range = non_negative(),
       .doc = "m, pairs closer than this produce contacts; 0 = automatic"},
      {.name = "pair_list_margin",
       .option = [](O& o) -> OptionRef { return &o.pair_list_margin; },
       .range = non_negative(),
       .auto_when_negative = true,
       .doc = "m, the broad phase's pairs are reused until a body has moved half this margin"},
  };
  return keys;
}

const std::vector<SectionKey<OutputOptions>>& output_keys() {
  using O = OutputOptions;
  constexpr std::int64_t most = std::numeric_limits<std::int64_t>::max();
  static const std::vector<SectionKey<O>> keys = {
      {.name = "directory",
       .option = [](O& o) -> OptionRef { return &o.directory; },
       .check =
           [](const TableReader& table, const O& o) {
             if (o.directory.empty()) table.fail_key("directory", "expected a folder name, got an empty string");
           },
       .doc = "output folder, relative to where rubble run is started"},
      {.name = "snapshot_every_steps",
       .option = [](O& o) -> OptionRef { return &o.snapshot_every_steps; },
       .low = 0,
       .high = most,
       .written = [](const O& o) { return o.snapshot_every_steps > 0; },
       .doc = "write a snapshot every N steps"},
      {.name = "snapshot_interval",
       .option = [](O& o) -> OptionRef { return &o.snapshot_interval; },
       .range = non_negative(),
       .written = [](const O& o) { return o.snapshot_every_steps <= 0; },
       .check =
           [](const TableReader& table, const O& o) {
             if (o.snapshot_every_steps > 0 && o.snapshot_interval > 0.0) {
               table.fail_key("snapshot_interval",
                              "expected either snapshot_every_steps or snapshot_interval, not both");
             }
           },
       .doc = "s of simulated time between snapshots; with both 0: 100 snapshots per run"},
      {.name = "progress_interval",
       .option = [](O& o) -> OptionRef { return &o.progress_interval; },
       .range = non_negative(),
       .doc = "s of wall time between progress lines"},
      {.name = "vtk",
       .option = [](O& o) -> OptionRef { return &o.write_vtk; },
       .doc = "also write the ParaView series during the run"},
      {.name = "keep_checkpoint_every",
       .option = [](O& o) -> OptionRef { return &o.keep_checkpoint_every; },
       .low = 0,
       .high = most,
       .written = [](const O& o) { return o.keep_checkpoint_every > 0; },
       .doc = "besides the newest two, keep the first checkpoint of every interval of N steps"},
  };
  return keys;
}

const std::vector<SectionKey<ContactLaw>>& contact_law_keys() {
  using O = ContactLaw;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "friction",
       .option = [](O& o) -> OptionRef { return &o.friction_coefficient; },
       .range = non_negative(),
       .required = true,
       .doc = "Coulomb's mu"},
      {.name = "restitution",
       .option = [](O& o) -> OptionRef { return &o.normal_restitution; },
       .range = closed(0.0, 1.0),
       .doc = "Newton's normal restitution e_n"},
      {.name = "tangential_restitution",
       .option = [](O& o) -> OptionRef { return &o.tangential_restitution; },
       .range = closed(0.0, 1.0),
       .written = [](const O& o) { return o.tangential_restitution > 0.0; },
       .doc = "e_t: Coulomb's law on u_t+ + e_t u_t-"},
      {.name = "cohesion",
       .option = [](O& o) -> OptionRef { return &o.cohesion; },
       .range = non_negative(),
       .written = [](const O& o) { return o.cohesion > 0.0; },
       .doc = "N, pull-off force of a pair in contact"},
      {.name = "work_of_adhesion",
       .option = [](O& o) -> OptionRef { return &o.work_of_adhesion; },
       .range = non_negative(),
       .written = [](const O& o) { return o.work_of_adhesion > 0.0; },
       .doc = "J/m^2, adds the size-dependent pull-off force 2 pi W r_eff"},
      {.name = "rolling_friction",
       .option = [](O& o) -> OptionRef { return &o.rolling_friction; },
       .range = non_negative(),
       .written = [](const O& o) { return o.rolling_friction > 0.0; },
       .doc = "rolling resistance of sphere contacts"},
      {.name = "twisting_friction",
       .option = [](O& o) -> OptionRef { return &o.twisting_friction; },
       .range = non_negative(),
       .written = [](const O& o) { return o.twisting_friction > 0.0; },
       .doc = "twisting (spin) resistance of sphere contacts"},
  };
  return keys;
}

}  // namespace rubble::scene_detail
