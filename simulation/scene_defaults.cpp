// The built-in scenes (`rubble run` without a scene file): the accretion study's smallest classic
// case (the LMGC90 accretion paper, docs/postprocessing.md "References"), with spheres or with
// random polyhedra. examples/accretion-1000.toml and examples/accretion-1000-polyhedra.toml
// hold the same texts (tests/scene/ keeps them equal).
#include <stdexcept>
#include <string_view>

#include "simulation/scene_file.hpp"

namespace rubble {

namespace {

/// What differs between the two built-in scenes. Both texts are composed from these pieces and
/// one template, rather than one derived from the other by search and replace, which would go on
/// silently (and make the wrong scene) once the text it searches for is edited.
struct AccretionVariant {
  std::string_view title;   ///< what the first comment line calls the scene
  std::string_view grains;  ///< the grains as the second comment line describes them
  std::string_view name;    ///< the scene's name, also the stem of its output folder
  std::string_view shape;   ///< the generator's shape line ("" for the default, spheres)
};

constexpr AccretionVariant spheres_variant{"the built-in default scene (`rubble run` without a scene file).",
                                           "10^3 spheres of diameter", "accretion-1000", ""};

// The paper's random polyhedra (10-70 vertices, elongation and platyness in [0.5, 1],
// circumscribed diameter 7.5-10 m): about 90 s of CPU to rest.
constexpr AccretionVariant polyhedra_variant{
    "the built-in default scene's polyhedra variant (`rubble run --default-scene polyhedra`).",
    "10^3 random convex polyhedra (CGAL hulls of 10-70 points on a\n"
    "# sphere, elongation and platyness in [0.5, 1]) of circumscribed diameter",
    "accretion-1000-polyhedra", "shape = \"polyhedron\"\n"};

/// The accretion study's smallest classic case run to rest: about 3000 steps, a minute or two
/// of CPU on 2 cores for the spheres (examples/README.md). The number of grains
/// (cells_per_side^3) and the rest criterion are the knobs that set the run time.
std::string accretion_scene_text(const AccretionVariant& variant) {
  std::string text = "# rubble scene file: ";
  text.append(variant.title);
  text += "\n# The accretion study (the LMGC90 accretion paper): ";
  text.append(variant.grains);
  text += R"( 7.5-10 m, uniform in volume fraction,
# one per cell of a cubic grid of mesh d_max = 10 m, at rest, collapse under their own gravity
# (Barnes-Hut tree) into a rubble pile; no friction, no restitution. The run stops when the
# grains are at rest. Reference: docs/scene-file.md. SI units throughout.
name = ")";
  text.append(variant.name);
  text += R"("
seed = 1

[time]
dt = "auto"                    # 1% of d_min over the free-fall velocity sqrt(2GM/R): 1.4 s here
end_time = 12000.0             # s, the latest end (7 characteristic times 1/sqrt(G rho))
until = "rest"                 # stop earlier, as soon as the grains are at rest:
rest_speed = "auto"            # 99% of the grains slower than 5% of v_ff (|v| + |w| r) ...
rest_duration = "auto"         # ... while Z and the contacts hold still, for 1/sqrt(G rho)

[gravity]
type = "tree"
G = 6.674e-11
theta = 0.5
order = 2

[output]
directory = ")";
  text.append(variant.name);
  text += R"(-output"
snapshot_interval = 60.0   # s of simulated time between snapshots
progress_interval = 5.0    # s of wall time between progress lines

[[materials]]
name = "regolith"
density = 5164.0   # kg/m^3, as printed in the paper

[[contact_laws]]
materials = ["regolith", "regolith"]
friction = 0.0
restitution = 0.0

[[generators]]
type = "cubic_grid"
)";
  text.append(variant.shape);
  text += R"(cells_per_side = 10
radius_min = 3.75
radius_max = 5.0
distribution = "uniform_volume_fraction"
)";
  return text;
}

}  // namespace

std::string default_scene_toml(DefaultScene variant) {
  switch (variant) {
    case DefaultScene::spheres:
      return accretion_scene_text(spheres_variant);
    case DefaultScene::polyhedra:
      return accretion_scene_text(polyhedra_variant);
  }
  throw std::invalid_argument("default_scene_toml: unknown DefaultScene value");
}

Scene default_scene(DefaultScene variant) { return parse_scene(default_scene_toml(variant), "<default scene>"); }

}  // namespace rubble
