#pragma once
// Small scenes and helpers shared by the scene-file tests (tests/scene/test_scene_*.cpp).
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace rubble::scene_test {

/// Two spheres in a box of plane walls, every section spelled out: the scene most parse tests start from.
inline constexpr const char* two_grains_in_a_box = R"(
name = "two"
seed = 9
[time]
dt = 2e-4
theta = 0.75
end_time = 0.5
[solver]
tolerance = 1e-6
max_iterations = 200
relaxation = 0.9
warm_start = false
penetration_correction = 0.5
max_correction_velocity = 0.25
polish_after = 15
polish_iterations = 7
polish_max_contacts = 700
[detection]
alert_distance = 0.001
pair_list_margin = 0.002
[gravity]
type = "uniform"
acceleration = [0, 0, -9.81]
[output]
directory = "out"
snapshot_every_steps = 50
progress_interval = 0
vtk = true
[[materials]]
name = "rock"
density = 3000
[[materials]]
name = "wall"
density = 1
[[contact_laws]]
materials = ["rock", "rock"]
friction = 0.5
restitution = 0.1
[[contact_laws]]
materials = ["wall", "rock"]
friction = 0.2
[[walls]]
type = "plane"
point = [0, 0, -1]
normal = [0, 0, 2]
material = "wall"
[[walls]]
type = "box"
center = [5, 0, 0]
half_extents = [1, 2, 3]
orientation = [0, 0, 0, 2]
material = "wall"
[[bodies]]
shape = "sphere"
radius = 0.5
position = [0, 0, 0]
velocity = [1, 2, 3]
angular_velocity = [0.1, 0.2, 0.3]
material = "rock"
[[bodies]]
shape = "sphere"
radius = 0.25
position = [2, 0, 0]
material = "rock"
)";

/// The whole text of a file.
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// A minimal self-gravitating scene around one generator table (its keys in `generator`).
inline std::string cloud_scene(const std::string& generator,
                               const std::string& time = "dt = \"auto\"\nend_time = 9000.0\n", int seed = 1) {
  return "seed = " + std::to_string(seed) + "\n[time]\n" + time +
         "[gravity]\ntype = \"tree\"\n[[materials]]\nname = \"rock\"\ndensity = 5164.0\n"
         "[default_contact_law]\nfriction = 0.0\n[[generators]]\n" +
         generator;
}

}  // namespace rubble::scene_test
