#pragma once
// Internal to the scene parser: what it gathers while reading a scene file (SceneDraft) and the
// parsers of the file's sections, which parse_scene (scene_file.cpp) calls in a fixed order. The
// order decides which problem of a file with several is reported, so it is part of the format's
// behaviour (tests/scene/bad/*.toml). Not part of the public API (simulation/scene_file.hpp is).
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/polyhedron.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "simulation/scene.hpp"
#include "simulation/scene_reader.hpp"

namespace rubble::scene_detail {

/// Grains may start overlapping a wall or each other by at most this fraction of the (smaller)
/// radius: the solver's penetration correction removes such small overlaps (e.g. a settled pile
/// written back with scene_to_toml), larger ones are mistakes in the scene.
inline constexpr double allowed_initial_overlap = 0.01;

/// Where a grain came from, for messages about it.
struct GrainOrigin {
  int body_entry = -1;               ///< index in [[bodies]], or -1
  int generator = -1;                ///< index in [[generators]], or -1
  std::uint64_t ordinal = 0;         ///< grain number within its generator
  const toml::node* node = nullptr;  ///< the entry's table
};

/// A grain to add: a sphere, or a polyhedron when `polyhedron` is set.
struct GrainSpec {
  double radius = 0;  ///< sphere radius, or the polyhedron's bounding radius about its centroid
  std::shared_ptr<const ConvexPolyhedron> polyhedron;  ///< body-frame shape, null for a sphere
  int material = 0;
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
  Vec3 velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
  int motion = -1;  ///< index into the parser's prescribed motions for a driven grain, else -1
  GrainOrigin origin{};
  /// A generated polyhedron not made yet: index into SceneDraft::polyhedron_recipes, else -1.
  /// Until make_polyhedra makes it, radius and position are those of the ball it is inscribed in.
  int pending_recipe = -1;
  std::uint64_t shape_seed = 0;  ///< the pending polyhedron's seed
  /// A polyhedron grain, made or still to make.
  bool is_polyhedron() const { return polyhedron != nullptr || pending_recipe >= 0; }
};

/// A wall to add.
struct WallSpec {
  bool is_plane = true;
  Vec3 position = Vec3::Zero();      ///< plane point or box centre
  Vec3 normal = Vec3::UnitZ();       ///< unit, plane only
  Vec3 half_extents = Vec3::Zero();  ///< box only
  Quat orientation = Quat::Identity();
  int material = 0;
  std::optional<PrescribedMotion> motion;  ///< set for a moving wall
  std::string path;
  const toml::node* node = nullptr;
};

/// The grain as named after its key: "the grain" for a [[bodies]] entry, "grain N" for a generator's.
std::string grain_label(const GrainOrigin& origin);
/// The grain named in full, for messages about another grain.
std::string grain_name(const GrainOrigin& origin);
/// The key of the grain's entry: "bodies[N]" or "generators[N]".
std::string grain_key(const GrainOrigin& origin);

/// Everything the parser has gathered: the scene so far (run options, materials, contact laws,
/// initial conditions) and the grains and walls, which become bodies once every check passed.
struct SceneDraft {
  SceneDraft(const std::string& file_name, const toml::table& root_table)
      : file(file_name), root(file_name, root_table, "", nullptr) {}

  const std::string& file;
  TableReader root;
  Scene scene;
  std::map<std::string, int> material_ids;
  std::optional<ContactLaw> default_law;
  std::vector<bool> law_defined;  ///< material pair (a * n + b) has a [[contact_laws]] entry
  std::vector<WallSpec> walls;
  std::vector<GrainSpec> grains;
  std::vector<PrescribedMotion> grain_motions;     ///< of the driven [[bodies]]
  std::vector<const toml::node*> condition_nodes;  ///< of the [[initial_conditions]] entries
  /// The [[inflow]] grains (shape, size, material), in order of due time (scene.inflow.grains):
  /// the model's last bodies, placed during the run. Until finish_inflows, in file order (each
  /// inflow's grains from inflow_first_grain[i], by number).
  std::vector<GrainSpec> inflow_grains;
  std::vector<std::size_t> inflow_first_grain;  ///< per [[inflow]] entry, until finish_inflows
  std::vector<double> inflow_mass_rates;        ///< per [[inflow]] entry: mass_rate (kg/s), 0 when given a rate
  /// How the generators' and inflows' polyhedra are made (GrainSpec::pending_recipe): the shape
  /// options, and the entry a failure is reported on.
  struct PolyhedronRecipe {
    TableReader entry;
    RandomPolyhedronOptions options;
  };
  std::vector<PolyhedronRecipe> polyhedron_recipes;
};

// scene_sections.cpp: [time], [solver], [detection], [gravity], [output].
void parse_time(SceneDraft& draft);
void parse_solver(SceneDraft& draft);
void parse_detection(SceneDraft& draft);
void parse_gravity(SceneDraft& draft);
void parse_output(SceneDraft& draft);
/// What depends on the grains: dt = "auto" and the automatic rest criterion (run_control.hpp).
void finish_time(SceneDraft& draft);

// scene_materials.cpp: [[materials]], [default_contact_law], [[contact_laws]].
void parse_materials(SceneDraft& draft);
void parse_contact_laws(SceneDraft& draft);
/// Material of a grain or wall: the `material` key, or the only material when there is one.
int material_of(const SceneDraft& draft, const TableReader& entry);

// scene_bodies.cpp: [[walls]], [[bodies]] (driven ones with their motion), [[initial_conditions]].
void parse_walls(SceneDraft& draft);
void parse_bodies(SceneDraft& draft);
void parse_initial_conditions(SceneDraft& draft);
/// The parameters of random polyhedra common to [[bodies]] and [[generators]] (defaults: the
/// accretion study's).
RandomPolyhedronOptions parse_random_polyhedron_options(const TableReader& entry);
/// Appends a grain, refusing more than max_packed_grains in a scene.
void add_grain(SceneDraft& draft, const GrainSpec& grain);

// scene_generators.cpp: [[generators]] and [[inflow]] (grains of a generator's kinds, inserted
// during the run: simulation/inflow.hpp).
void parse_generators(SceneDraft& draft);
void parse_inflows(SceneDraft& draft);
/// The generators' and inflows' random polyhedra (CGAL hulls, seconds for 10^5 of them), made
/// after the checks that need only the grains' materials and kinds, so that a mistake there is
/// reported at once; in parallel, the first failure in file order reported.
void make_polyhedra(SceneDraft& draft);
/// The inflows' rates (mass_rate needs the polyhedra's volumes) and due times; inflow_grains
/// sorted by due time.
void finish_inflows(SceneDraft& draft);

// scene_checks.cpp: the checks of the scene as a whole, before its bodies are made.
/// Every pair of materials that can touch (grain-grain, grain-wall) needs a law, unless a
/// [default_contact_law] covers the missing ones.
void check_contact_law_coverage(const SceneDraft& draft);
/// Rolling and twisting resistance act on sphere contacts only: a law with rolling_friction or
/// twisting_friction > 0 for a pair where a polyhedron grain's material meets a material that can
/// touch it is refused (nlgs_solver/README.md, "Rolling and twisting resistance").
void check_rotation_resistance_shapes(const SceneDraft& draft);
/// Two plane walls facing away from each other (normals opposite) leave no room between them.
void check_walls_have_an_inside(const SceneDraft& draft);
void check_grains_inside_walls(const SceneDraft& draft);
/// No two spheres interpenetrate by more than allowed_initial_overlap of the smaller radius.
void check_grains_do_not_overlap(const SceneDraft& draft);

}  // namespace rubble::scene_detail
