// `rubble pack KIND ...`: writes a scene file holding an initial packing (preprocessing/packing.hpp)
// and what an accretion or deposit run needs around it (material, contact law, gravity, time
// control). KIND is cubic-grid (the accretion study's cloud), cloud (a random loose cloud in a
// ball) or box (a deposit rained into an open box under uniform gravity).
//
// The scene is written with a generator entry and the seed, so the file is small and the grains
// are reproducible from it; --explicit expands every grain instead (scene_to_toml). Either way
// the text is parsed back before it is written, so a file `rubble pack` writes always runs. The
// text itself comes from simulation/pack_scene.hpp, shared with the Python module (rubble.pack).
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "core/units.hpp"
#include "simulation/pack_scene.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

/// The command line of `rubble pack`: the scene's options and where to write it.
struct PackArguments : PackOptions {
  std::string output = "-";  ///< -o, "-" = standard output
};

int bad_input(const std::string& message) {
  std::cerr << "rubble pack: error: " << message << "\n";
  return exit_bad_input;
}

int pack_command(const PackArguments& args) {
  std::string text;
  try {
    text = pack_scene_text(args);
  } catch (const std::exception& e) {
    return bad_input(e.what());
  }
  try {
    const Scene scene = parse_scene(text, "<rubble pack " + args.kind + ">");
    if (args.explicit_grains) text = scene_to_toml(scene);
    std::cerr << "rubble pack: " << scene.model.body_count() << " bodies, dt = " << scene.run.step.integrator.time_step
              << " s (auto), run until at rest or t = " << scene.run.end_time << " s\n";
  } catch (const SceneError& e) {
    return bad_input(e.what());
  }
  return write_scene_text("pack", args.output, text);
}

}  // namespace

void register_pack_command(CLI::App& app) {
  auto args = std::make_shared<PackArguments>();
  CLI::App* pack = app.add_subcommand("pack", "Write a scene file with an initial packing (cubic-grid | cloud | box)");
  pack->add_option("kind", args->kind,
                   "cubic-grid: n = k^3 grains, one per cell of a grid of mesh dmax (the accretion study); cloud: a "
                   "random loose cloud in a ball; box: a deposit rained into an open box under uniform gravity")
      ->required()
      ->check(CLI::IsMember({"cubic-grid", "cloud", "box"}));
  pack->add_option("--n", args->count, "Number of grains (cubic-grid: a cube k^3)")->check(CLI::Range(1.0, 1e8));
  pack->add_option("--shape", args->shape,
                   "spheres, polyhedra (random convex, as in the LMGC90 accretion paper) or mix")
      ->check(CLI::IsMember({"spheres", "polyhedra", "mix"}));
  pack->add_option("--polyhedron-fraction", args->polyhedron_fraction, "mix: share of polyhedra by number")
      ->check(CLI::Range(0.0, 1.0));
  pack->add_option("--dmin", args->d_min, "Smallest diameter, m (circumscribed for polyhedra)")
      ->check(CLI::PositiveNumber);
  pack->add_option("--dmax", args->d_max, "Largest diameter, m (the grid's mesh)")->check(CLI::PositiveNumber);
  pack->add_option("--distribution", args->distribution, "volume-fraction (the study's), uniform, monodisperse or bins")
      ->check(CLI::IsMember({"volume-fraction", "uniform", "monodisperse", "bins"}));
  pack->add_option("--bins", args->bins, "bins: DIAMETER:FRACTION,... e.g. 8:0.3,10:0.7");
  pack->add_option("--bin-fractions", args->bin_fractions, "bins: fractions of the volume or of the number")
      ->check(CLI::IsMember({"volume", "number"}));
  pack->add_option("--density", args->density, "Grain density, kg/m^3")->check(CLI::PositiveNumber);
  pack->add_option("--friction", args->friction, "Coulomb friction mu")->check(CLI::NonNegativeNumber);
  pack->add_option("--restitution", args->restitution, "Normal restitution e_n")->check(CLI::Range(0.0, 1.0));
  pack->add_option("--seed", args->seed, "Seed of the packing (same seed, same file)");
  pack->add_option("--volume-fraction", args->volume_fraction, "cloud: grain volume / ball volume")
      ->check(CLI::Range(1e-6, 0.3));
  pack->add_option("--cloud-radius", args->cloud_radius, "cloud: ball radius, m (instead of --volume-fraction)")
      ->check(CLI::PositiveNumber);
  pack->add_option("--box-width", args->box_width, "box: inner width, m (default 10 dmax)")->check(CLI::PositiveNumber);
  pack->add_option("--g", args->g, "box: gravity, m/s^2")->check(CLI::PositiveNumber);
  pack->add_option("--end-time", args->end_time,
                   "Latest end of the run, s (default: 7/sqrt(G rho) for clouds, 20 fall times for a box)")
      ->check(CLI::PositiveNumber);
  pack->add_option("--name", args->name, "Scene name (default KIND-N-SHAPE)");
  pack->add_option("-o,--out", args->output, "Scene file to write (default -: standard output)");
  pack->add_flag("--explicit", args->explicit_grains, "List every grain in the file instead of the generator and seed");
  pack->callback([args] {
    if (args->distribution == "bins" && args->bins.empty())
      throw CLI::ValidationError("--bins", "needed with --distribution bins");
    if (args->d_max < args->d_min && args->distribution != "monodisperse" && args->distribution != "bins") {
      throw CLI::ValidationError("--dmax", "expected dmax >= dmin");
    }
    const int code = pack_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
