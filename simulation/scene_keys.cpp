// The key tables of the top level and of the settings sections: [time], [solver], [detection],
// [gravity], [output] and the contact laws (scene_keys.hpp). The body sections' tables are in
// scene_body_keys.cpp.
#include "simulation/scene_keys.hpp"

#include <limits>

#include "gravity/gravity.hpp"

namespace rubble::scene_detail {

const std::vector<SectionKey<Scene>>& top_level_keys() {
  using O = Scene;
  /// A section: a table read by its own parser (scene_parser.hpp), in the order of the layout.
  const auto section = [](std::string_view name, std::string_view doc) {
    return SectionKey<O>{.name = name, .type = "table", .doc = doc};
  };
  static const std::vector<SectionKey<O>> keys = {
      {.name = "name",
       .option = [](O& o) -> OptionRef { return &o.name; },
       .doc = "the scene's name; default: the file name without extension"},
      // Read by hand: an unsigned 64-bit seed read as a non-negative TOML integer.
      {.name = "seed",
       .type = "integer",
       .read =
           [](const TableReader& table, O& o) {
             o.run.seed =
                 static_cast<std::uint64_t>(table.integer_or("seed", 1, 0, std::numeric_limits<std::int64_t>::max()));
           },
       .write =
           [](const O& o) { return std::to_string(static_cast<std::int64_t>(o.run.seed & 0x7FFFFFFFFFFFFFFFULL)); },
       .doc = "seed of every random draw of the scene"},
      section("time", "time stepping (required)"),
      section("solver", "the contact solver"),
      section("detection", "contact detection"),
      section("gravity", "gravity (none without it)"),
      section("output", "what the run writes"),
      section("materials", "one entry per material"),
      section("contact_laws", "one entry per pair of materials"),
      section("default_contact_law", "the law of pairs without an entry"),
      section("walls", "walls"),
      section("bodies", "grains one by one"),
      section("generators", "grains by the thousand"),
      section("initial_conditions", "a rigid motion given to groups of grains"),
      section("inflow", "grains inserted during the run at a rate"),
  };
  return keys;
}

const std::vector<SectionKey<RunOptions>>& time_keys() {
  using O = RunOptions;
  const auto with_rest = [](const O& o) { return o.until_rest; };
  static const std::vector<SectionKey<O>> keys = {
      {.name = "dt",
       .option = [](O& o) -> OptionRef { return &o.step.integrator.time_step; },
       .range = positive(),
       .automatic = [](O& o) { return &o.automatic_time_step; },
       .required = true,
       .doc = "s, the time step h; \"auto\": chosen from the scene (finish_time)"},
      {.name = "theta",
       .option = [](O& o) -> OptionRef { return &o.step.integrator.theta; },
       .range = closed(0.5, 1.0),
       .doc = "theta of the Moreau-Jean step in Moreau's midpoint form"},
      {.name = "end_time",
       .option = [](O& o) -> OptionRef { return &o.end_time; },
       .range = positive(),
       .required = true,
       .doc = "s, simulated time at which the run stops"},
      // Read by hand: a word that sets a flag, and the rest_ keys are refused without "rest"
      // (checked here, before any of their values is read).
      {.name = "until",
       .choices = {"end_time", "rest"},
       .written = with_rest,
       .read =
           [](const TableReader& table, O& o) {
             o.until_rest = table.optional_choice("until", {"end_time", "rest"}).value_or("end_time") == "rest";
             for (const auto& key : time_keys()) {
               if (key.name.rfind("rest_", 0) == 0 && table.has(key.name) && !o.until_rest) {
                 table.fail_key(key.name, "only used with until = \"rest\" (expected that key too, or no " +
                                              std::string(key.name) + ")");
               }
             }
           },
       .write = [](const O&) { return std::string("\"rest\""); },
       .doc = "\"rest\": also stop as soon as the grains are at rest"},
      {.name = "rest_speed",
       .option = [](O& o) -> OptionRef { return &o.rest.speed; },
       .range = positive(),
       .automatic = [](O& o) { return &o.automatic_rest_speed; },
       .written = with_rest,
       .doc = "m/s, the rest speed the speed quantile must stay below"},
      {.name = "rest_quantile",
       .option = [](O& o) -> OptionRef { return &o.rest.quantile; },
       .range = Range{0.0, 1.0, false, true},
       .written = with_rest,
       .doc = "which quantile of the grain speeds is held to rest_speed"},
      {.name = "rest_coordination_change",
       .option = [](O& o) -> OptionRef { return &o.rest.coordination_change; },
       .range = non_negative(),
       .automatic = [](O& o) { return &o.automatic_rest_coordination_change; },
       .written = with_rest,
       .doc = "largest change of the coordination number over the rest duration"},
      {.name = "rest_contact_change",
       .option = [](O& o) -> OptionRef { return &o.rest.contact_change; },
       .range = closed(0.0, 1.0),
       .written = with_rest,
       .doc = "largest fraction of contacts created or broken over the rest duration"},
      {.name = "rest_duration",
       .option = [](O& o) -> OptionRef { return &o.rest.duration; },
       .range = non_negative(),
       .automatic = [](O& o) { return &o.automatic_rest_duration; },
       .written = with_rest,
       .doc = "s, how long every rest condition must hold"},
  };
  return keys;
}

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
       .doc = "omega: r <- omega r_local + (1 - omega) r_old; above 1 only between plain first and last sweeps"},
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
      {.name = "cluster_polish_max_contacts",
       .option = [](O& o) -> OptionRef { return &o.cluster_polish_max_contacts; },
       .low = 0,
       .high = 100'000'000,
       .doc = "larger steps: the few grains holding a stalled residual are polished alone, up to this many points; 0 = "
              "never"},
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
      {.name = "anderson_depth",
       .option = [](O& o) -> OptionRef { return &o.anderson_depth; },
       .low = 0,
       .high = 50,
       .doc = "sweeps remembered by the Anderson acceleration of the sweeps; 0 = off"},
      {.name = "anderson_max_contacts",
       .option = [](O& o) -> OptionRef { return &o.anderson_max_contacts; },
       .low = 0,
       .high = 100'000'000,
       .doc = "steps with more contacts are not accelerated (the history's memory)"},
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

const std::vector<std::string_view>& gravity_types() {
  static const std::vector<std::string_view> types = {"none", "uniform", "direct", "tree", "central"};
  return types;
}

namespace {

using Gravity = GravitySettings;

/// The `type` row of one [gravity] type (`word`, a literal): read by parse_gravity (it picks the
/// table), written as the type's word.
SectionKey<Gravity> gravity_type_row(std::string_view word, std::string (*write)(const Gravity&)) {
  return {.name = "type",
          .required = true,
          .choices = {word},
          .write = write,
          .doc = "which gravity; decides the other keys"};
}

SectionKey<Gravity> gravity_constant_row(OptionRef (*option)(Gravity&)) {
  return {.name = "G", .option = option, .range = positive(), .doc = "m^3 kg^-1 s^-2, gravitational constant"};
}

/// The keys of self-gravity, direct or tree (`tree_keys` between softening and evaluate_every).
std::vector<SectionKey<Gravity>> self_gravity_keys(const SectionKey<Gravity>& type,
                                                   const std::vector<SectionKey<Gravity>>& tree_keys) {
  using O = Gravity;
  std::vector<SectionKey<O>> keys = {
      type,
      gravity_constant_row([](O& o) -> OptionRef { return &o.self_gravity.G; }),
      // Read by hand: one number sets the softening's kind (none at 0) and length.
      {.name = "softening",
       .type = "number",
       .read =
           [](const TableReader& table, O& o) {
             auto& softening = o.self_gravity.softening;
             const double length = table.number_or("softening", 0.0, non_negative());
             softening.kind = length > 0.0 ? gravity::Softening::Kind::plummer : gravity::Softening::Kind::none;
             softening.length = length;
           },
       .write =
           [](const O& o) {
             const auto& softening = o.self_gravity.softening;
             return format_number(softening.kind == gravity::Softening::Kind::plummer ? softening.length : 0.0);
           },
       .doc = "m, Plummer softening length (0: exact 1/r)"},
  };
  keys.insert(keys.end(), tree_keys.begin(), tree_keys.end());
  keys.push_back(
      {.name = "evaluate_every",
       .option = [](O& o) -> OptionRef { return &o.evaluate_every; },
       .low = 1,
       .high = 1'000'000,  // the field held in between (external_forces.cpp); capped so a typo cannot freeze gravity
       .written = [](const O& o) { return o.evaluate_every != 1; },
       .read_first = true,
       .written_last = true,
       .doc = "self-gravity evaluated every k steps, held in between"});
  // Read by hand: a GPU backend that cannot run here is refused now, at its line, not at the
  // first step.
  keys.push_back({.name = "backend",
                  .choices = {"cpu", "cuda"},
                  .written = [](const O& o) { return o.self_gravity.backend != gravity::Backend::cpu; },
                  .read =
                      [](const TableReader& table, O& o) {
                        if (table.optional_choice("backend", {"cpu", "cuda"}).value_or("cpu") != "cuda") return;
                        o.self_gravity.backend = gravity::Backend::cuda;
                        const std::string reason = gravity::backend_unavailable_reason(o.self_gravity);
                        if (!reason.empty()) table.fail_key("backend", "\"cuda\" cannot run here: " + reason);
                      },
                  .write =
                      [](const O& o) {
                        // Appended piece by piece: `"\"" + std::string` trips GCC 12's -Wrestrict false positive.
                        std::string word = "\"";
                        return word.append(gravity::to_string(o.self_gravity.backend)).append("\"");
                      },
                  .doc = "where the self-gravity is computed"});
  return keys;
}

}  // namespace

const std::vector<SectionKey<GravitySettings>>& gravity_keys(std::string_view type) {
  using O = Gravity;
  static const std::vector<SectionKey<O>> none = {
      gravity_type_row("none", [](const O&) { return std::string("\"none\""); })};
  static const std::vector<SectionKey<O>> uniform = {
      gravity_type_row("uniform", [](const O&) { return std::string("\"uniform\""); }),
      {.name = "acceleration",
       .option = [](O& o) -> OptionRef { return &o.acceleration; },
       .required = true,
       .doc = "m/s^2, the uniform field g"},
  };
  static const std::vector<SectionKey<O>> direct =
      self_gravity_keys(gravity_type_row("direct", [](const O&) { return std::string("\"direct\""); }), {});
  static const std::vector<SectionKey<O>> tree = self_gravity_keys(
      gravity_type_row("tree", [](const O&) { return std::string("\"tree\""); }),
      {{.name = "theta",
        .option = [](O& o) -> OptionRef { return &o.self_gravity.theta; },
        .range = Range{0.0, 2.0, false, true},
        .doc = "opening angle of the tree"},
       {.name = "order",
        .option = [](O& o) -> OptionRef { return &o.self_gravity.order; },
        .low = 1,
        .high = 2,
        .doc = "multipole order: 1 monopole, 2 quadrupole"},
       {.name = "leaf_size",
        .option = [](O& o) -> OptionRef { return &o.self_gravity.leaf_size; },
        .low = 1,
        .high = 1'000'000,
        .doc = "largest number of grains in a tree leaf"},
       {.name = "group_size",
        .option = [](O& o) -> OptionRef { return &o.self_gravity.group_size; },
        .low = 1,
        .high = 1'000'000,
        .doc = "targets walking the tree together"},
       {.name = "precision",
        .choices = {"double", "single"},
        .written = [](const O& o) { return o.self_gravity.precision != gravity::KernelPrecision::double_precision; },
        .read =
            [](const TableReader& table, O& o) {
              if (table.optional_choice("precision", {"double", "single"}).value_or("double") == "single")
                o.self_gravity.precision = gravity::KernelPrecision::single_precision;
            },
        .write =
            [](const O& o) {
              std::string word = "\"";
              return word.append(gravity::to_string(o.self_gravity.precision)).append("\"");
            },
        .doc = "arithmetic of the tree's kernels (single: 1.3-1.6x faster, each term within "
               "~1e-6 of double)"}});
  // A fixed point mass (external_forces.hpp, CentralField): the Plummer-softened Kepler field.
  static const std::vector<SectionKey<O>> central = {
      gravity_type_row("central", [](const O&) { return std::string("\"central\""); }),
      {.name = "centre",
       .option = [](O& o) -> OptionRef { return &o.central.centre; },
       .range = coordinate(),
       .required = true,
       .doc = "m, position of the point mass"},
      {.name = "mass",
       .option = [](O& o) -> OptionRef { return &o.central.mass; },
       .range = positive(),
       .required = true,
       .doc = "kg, the point mass M"},
      gravity_constant_row([](O& o) -> OptionRef { return &o.central.G; }),
      {.name = "softening",
       .option = [](O& o) -> OptionRef { return &o.central.softening; },
       .range = non_negative(),
       .doc = "m, Plummer softening length (0: the exact point-mass field)"},
  };
  if (type == "none") return none;
  if (type == "uniform") return uniform;
  if (type == "direct") return direct;
  if (type == "tree") return tree;
  return central;
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
