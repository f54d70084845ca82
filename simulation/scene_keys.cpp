#include "simulation/scene_keys.hpp"

namespace rubble::scene_detail {

const std::vector<SectionKey<SolverOptions>>& solver_keys() {
  using O = SolverOptions;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "tolerance", .option = [](O& o) -> OptionRef { return &o.tolerance; }, .range = positive(),
       .doc = "stop the sweeps when the residual is below it"},
      {.name = "max_iterations", .option = [](O& o) -> OptionRef { return &o.max_iterations; }, .low = 1,
       .high = 100'000'000, .doc = "sweeps at most per step"},
      {.name = "relaxation", .option = [](O& o) -> OptionRef { return &o.relaxation; }, .range = open(0.0, 2.0),
       .doc = "omega: r <- omega r_local + (1 - omega) r_old"},
      {.name = "warm_start", .option = [](O& o) -> OptionRef { return &o.warm_start; },
       .doc = "start from last step's impulses of persistent contacts"},
      {.name = "penetration_correction", .option = [](O& o) -> OptionRef { return &o.overlap_recovery.fraction; },
       .range = closed(0.0, 1.0), .doc = "fraction of the overlap beyond allowed_overlap removed per step"},
      {.name = "max_correction_velocity",
       .option = [](O& o) -> OptionRef { return &o.overlap_recovery.max_velocity; }, .range = non_negative(),
       .doc = "m/s, cap on a contact's recovery pseudo-velocity"},
      {.name = "allowed_overlap", .option = [](O& o) -> OptionRef { return &o.overlap_recovery.allowed_overlap; },
       .range = closed(0.0, 1.0), .doc = "overlap left alone, as a fraction of the smaller bounding radius"},
      {.name = "polish_after", .option = [](O& o) -> OptionRef { return &o.polish_after; }, .low = 0,
       .high = 100'000'000, .doc = "sweeps without convergence before a Newton polish; 0 = never"},
      {.name = "polish_iterations", .option = [](O& o) -> OptionRef { return &o.polish_iterations; }, .low = 1,
       .high = 10'000, .doc = "Newton (Levenberg-Marquardt) steps per polish at most"},
      {.name = "polish_max_contacts", .option = [](O& o) -> OptionRef { return &o.polish_max_contacts; }, .low = 0,
       .high = 100'000'000, .doc = "steps with more contacts are not polished"},
      {.name = "polish_attempts_per_step", .option = [](O& o) -> OptionRef { return &o.polish_attempts_per_step; },
       .low = 1, .high = 100, .doc = "Newton polishes per step at most"},
      {.name = "block_count", .option = [](O& o) -> OptionRef { return &o.block_count; }, .low = 1,
       .high = 1'000'000, .doc = "spatial blocks of the sweep order (Morton-order ranges swept concurrently)"},
  };
  return keys;
}

const std::vector<SectionKey<DetectionOptions>>& detection_keys() {
  using O = DetectionOptions;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "alert_distance", .option = [](O& o) -> OptionRef { return &o.alert_distance; },
       .range = non_negative(), .doc = "m, pairs closer than this produce contacts; 0 = automatic"},
      {.name = "pair_list_margin", .option = [](O& o) -> OptionRef { return &o.pair_list_margin; },
       .range = non_negative(), .auto_when_negative = true,
       .doc = "m, the broad phase's pairs are reused until a body has moved half this margin"},
  };
  return keys;
}

}  // namespace rubble::scene_detail
