#pragma once
// The scene text `rubble pack` writes: an initial packing (preprocessing/packing.hpp, through a
// scene-file generator) and what an accretion or deposit run needs around it (material, contact
// law, gravity, time control). Shared by the command line (apps/cmd_pack.cpp) and the Python
// module (`rubble.pack`), so both write the same file for the same options.
//
// KIND is cubic-grid (the accretion study's cloud), cloud (a random loose cloud in a ball) or box
// (a deposit rained into an open box under uniform gravity). The scene is written with a
// generator entry and the seed, so the text is small and the grains are reproducible from it.
#include <cstdint>
#include <string>

#include "core/units.hpp"

namespace rubble {

/// The options of `rubble pack` (the command's flags, same names and defaults).
struct PackOptions {
  std::string kind = "cubic-grid";               ///< cubic-grid, cloud or box
  std::uint64_t count = 1000;                    ///< --n: number of grains (cubic-grid: a cube k^3)
  std::string shape = "spheres";                 ///< --shape: spheres, polyhedra or mix
  double polyhedron_fraction = 0.5;              ///< --polyhedron-fraction (mix): share of polyhedra by number
  double d_min = 7.5;                            ///< --dmin: smallest diameter, m
  double d_max = 10.0;                           ///< --dmax: largest diameter, m (the grid's mesh)
  std::string distribution = "volume-fraction";  ///< --distribution: volume-fraction, uniform, monodisperse, bins
  std::string bins;                              ///< --bins: "d:f,d:f,..." (distribution = bins)
  std::string bin_fractions = "volume";          ///< --bin-fractions: volume or number
  double density = 5164.0;                       ///< --density: kg/m^3
  double friction = 0.0;                         ///< --friction: Coulomb's mu
  double restitution = 0.0;                      ///< --restitution: Newton's e_n
  std::uint64_t seed = 1;                        ///< --seed
  double volume_fraction = 0.1;                  ///< --volume-fraction (cloud): grain volume / ball volume
  double cloud_radius = 0.0;                     ///< --cloud-radius (cloud): m, overrides volume_fraction when > 0
  double box_width = 0.0;                        ///< --box-width (box): m, 0 = 10 d_max
  double g = units::standard_gravity;            ///< --g (box): m/s^2
  double end_time = 0.0;                         ///< --end-time: s, 0 = automatic
  std::string name;                              ///< --name: scene name ("" = KIND-N-SHAPE)
  bool explicit_grains = false;                  ///< --explicit: every grain listed (recorded in the header line)
};

/// Checks the options that the scene parser would not check itself (kind, shape, distribution,
/// bin fractions, d_max >= d_min, a cube count for cubic-grid); throws std::invalid_argument with
/// the flag's name and what was expected.
void check_pack_options(const PackOptions& options);

/// The `rubble pack` command line that writes this scene again (every option spelt out).
std::string pack_command_line(const PackOptions& options);

/// The scene text, with a generator entry (the file `rubble pack` writes without --explicit).
/// Throws std::invalid_argument for bad options (check_pack_options, malformed --bins).
std::string pack_scene_text(const PackOptions& options);

}  // namespace rubble
