// `rubble pack KIND ...`: writes a scene file holding an initial packing (preprocessing/packing.hpp)
// and what an accretion or deposit run needs around it (material, contact law, gravity, time
// control). KIND is cubic-grid (the accretion study's cloud), cloud (a random loose cloud in a
// ball) or box (a deposit rained into an open box under uniform gravity).
//
// The scene is written with a generator entry and the seed, so the file is small and the grains
// are reproducible from it; --explicit expands every grain instead (scene_to_toml). Either way
// the text is parsed back before it is written, so a file `rubble pack` writes always runs.
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "core/units.hpp"
#include "preprocessing/packing.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

/// The command line of `rubble pack`.
struct PackArguments {
  std::string kind;                      ///< cubic-grid, cloud or box
  std::uint64_t count = 1000;            ///< --n
  std::string shape = "spheres";         ///< spheres, polyhedra or mix
  double polyhedron_fraction = 0.5;      ///< --polyhedron-fraction (mix)
  double d_min = 7.5;                    ///< m
  double d_max = 10.0;                   ///< m
  std::string distribution = "volume-fraction";  ///< volume-fraction, uniform, monodisperse, bins
  std::string bins;                      ///< "d:f,d:f,..."
  std::string bin_fractions = "volume";  ///< volume or number
  double density = 5164.0;               ///< kg/m^3
  double friction = 0.0;                 ///< mu
  double restitution = 0.0;              ///< e_n
  std::uint64_t seed = 1;
  double volume_fraction = 0.1;          ///< cloud: grain volume / ball volume
  double cloud_radius = 0.0;             ///< cloud: m, overrides volume_fraction
  double box_width = 0.0;                ///< box: m, 0 = 10 d_max
  double g = units::standard_gravity;    ///< box: m/s^2
  double end_time = 0.0;                 ///< s, 0 = automatic
  std::string name;                      ///< scene name
  std::string output = "-";              ///< -o, "-" = standard output
  bool explicit_grains = false;          ///< --explicit
};

int bad_input(const std::string& message) {
  std::cerr << "rubble pack: error: " << message << "\n";
  return exit_bad_input;
}

std::string number(double x) { return fmt::format("{}", x); }

/// The size keys of a generator from the arguments.
std::string size_keys(const PackArguments& a) {
  if (a.distribution == "monodisperse") {
    return fmt::format("distribution = \"monodisperse\"\nradius = {}\n", number(0.5 * a.d_max));
  }
  if (a.distribution == "bins") {
    std::string list;
    std::stringstream in(a.bins);
    std::string item;
    while (std::getline(in, item, ',')) {
      const auto colon = item.find(':');
      if (colon == std::string::npos) throw std::invalid_argument("--bins: expected DIAMETER:FRACTION pairs, got \"" + item + "\"");
      std::size_t used = 0;
      const double d = std::stod(item.substr(0, colon), &used);
      const double f = std::stod(item.substr(colon + 1));
      list += fmt::format("{}[{}, {}]", list.empty() ? "" : ", ", number(d), number(f));
    }
    if (list.empty()) throw std::invalid_argument("--bins: expected DIAMETER:FRACTION pairs, e.g. 8:0.5,10:0.5");
    return fmt::format("distribution = \"bins\"\nbins = [{}]\nbin_fractions = \"{}\"\n", list, a.bin_fractions);
  }
  return fmt::format("distribution = \"{}\"\nradius_min = {}\nradius_max = {}\n",
                     a.distribution == "uniform" ? "uniform_radius" : "uniform_volume_fraction", number(0.5 * a.d_min),
                     number(0.5 * a.d_max));
}

std::string shape_keys(const PackArguments& a) {
  if (a.shape == "polyhedra") return "shape = \"polyhedron\"\n";
  if (a.shape == "mix") return fmt::format("shape = \"mix\"\npolyhedron_fraction = {}\n", number(a.polyhedron_fraction));
  return "shape = \"sphere\"\n";
}

/// The `rubble pack` command that writes this scene again (every option spelt out).
std::string command_line(const PackArguments& a) {
  std::string line = fmt::format("rubble pack {} --n {} --shape {}", a.kind, a.count, a.shape);
  if (a.shape == "mix") line += fmt::format(" --polyhedron-fraction {}", number(a.polyhedron_fraction));
  line += fmt::format(" --distribution {}", a.distribution);
  if (a.distribution == "bins") {
    line += fmt::format(" --bins {} --bin-fractions {}", a.bins, a.bin_fractions);
  } else {
    line += fmt::format(" --dmin {} --dmax {}", number(a.d_min), number(a.d_max));
  }
  line += fmt::format(" --density {} --friction {} --restitution {} --seed {}", number(a.density), number(a.friction),
                      number(a.restitution), a.seed);
  if (a.kind == "cloud") {
    line += a.cloud_radius > 0.0 ? fmt::format(" --cloud-radius {}", number(a.cloud_radius))
                                 : fmt::format(" --volume-fraction {}", number(a.volume_fraction));
  }
  if (a.kind == "box" && a.box_width > 0.0) line += fmt::format(" --box-width {}", number(a.box_width));
  if (a.kind == "box") line += fmt::format(" --g {}", number(a.g));
  if (a.end_time > 0.0) line += fmt::format(" --end-time {}", number(a.end_time));
  if (!a.name.empty()) line += " --name " + a.name;
  if (a.explicit_grains) line += " --explicit";
  return line;
}

/// The scene text, with a generator.
std::string scene_text(const PackArguments& a) {
  std::ostringstream out;
  const bool box = a.kind == "box";
  const std::string name = a.name.empty() ? fmt::format("{}-{}-{}", a.kind, a.count, a.shape) : a.name;
  out << "# rubble scene file written by rubble pack; reference: docs/scene-file.md. Regenerate with:\n# "
      << command_line(a) << "\n";
  out << "name = \"" << name << "\"\nseed = " << a.seed << "\n\n";
  // Time: dt from the scene, until at rest; the end time caps the run.
  double end_time = a.end_time;
  if (!(end_time > 0.0)) {
    // Accretion: 7 characteristic times 1/sqrt(G rho) (the study's plateau starts near 4.4 of
    // them, 125 min); deposit: 20 fall times over the box height.
    end_time = box ? 20.0 * std::sqrt(2.0 * 10.0 * a.d_max / a.g) : std::round(7.0 / std::sqrt(units::gravitational_constant * a.density));
  }
  out << "[time]\ndt = \"auto\"\nend_time = " << number(end_time) << "\nuntil = \"rest\"\n\n";
  if (box) {
    out << "[gravity]\ntype = \"uniform\"\nacceleration = [0.0, 0.0, " << number(-a.g) << "]\n\n";
  } else {
    out << "[gravity]\ntype = \"tree\"\n\n";
  }
  out << "[output]\ndirectory = \"" << name << "-output\"\n\n";
  out << "[[materials]]\nname = \"grain\"\ndensity = " << number(a.density) << "\n\n";
  out << "[default_contact_law]\nfriction = " << number(a.friction) << "\nrestitution = " << number(a.restitution)
      << "\n\n";
  if (a.kind == "cubic-grid") {
    const auto k = static_cast<std::uint64_t>(std::llround(std::cbrt(static_cast<double>(a.count))));
    if (k * k * k != a.count) {
      throw std::invalid_argument(fmt::format("--n {} is not a cube k^3 (the cubic grid has n = k^3 grains; nearest: {} or {})",
                                              a.count, k * k * k, (k + 1) * (k + 1) * (k + 1)));
    }
    out << "[[generators]]\ntype = \"cubic_grid\"\ncells_per_side = " << k << "\ncell_size = " << number(a.d_max) << "\n";
  } else if (a.kind == "cloud") {
    out << "[[generators]]\ntype = \"sphere_cloud\"\ncount = " << a.count << "\n";
    if (a.cloud_radius > 0.0) {
      out << "cloud_radius = " << number(a.cloud_radius) << "\n";
    } else {
      out << "volume_fraction = " << number(a.volume_fraction) << "\n";
    }
  } else {
    // An open box of width W: floor at z = 0 and four sides; the deposit region is as high as
    // the loose grid (cells of 1.1 d_max) needs.
    const double width = a.box_width > 0.0 ? a.box_width : 10.0 * a.d_max;
    const double cell = 1.1 * a.d_max;
    const double per_layer = std::pow(std::floor(width / cell * (1.0 + 1e-9)), 2);
    if (!(per_layer >= 1.0)) throw std::invalid_argument("--box-width must hold at least one grain (>= 1.1 dmax)");
    const double layers = std::ceil(static_cast<double>(a.count) / per_layer);
    const double h = 0.5 * width;
    out << "[[walls]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\n";
    for (const auto& [px, py, nx, ny] : {std::array<double, 4>{-h, 0, 1, 0}, {h, 0, -1, 0}, {0, -h, 0, 1}, {0, h, 0, -1}}) {
      out << fmt::format("[[walls]]\ntype = \"plane\"\npoint = [{}, {}, 0.0]\nnormal = [{}, {}, 0.0]\n\n", number(px),
                         number(py), number(nx), number(ny));
    }
    out << "[[generators]]\ntype = \"box_deposit\"\ncount = " << a.count << "\nregion_min = [" << number(-h) << ", "
        << number(-h) << ", 0.0]\nregion_max = [" << number(h) << ", " << number(h) << ", "
        << number(layers * cell * (1.0 + 1e-6)) << "]\n";
  }
  out << shape_keys(a) << size_keys(a);
  return out.str();
}

int pack_command(const PackArguments& args) {
  std::string text;
  try {
    text = scene_text(args);
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
  if (args.output == "-") {
    std::cout << text;
    return exit_ok;
  }
  std::ofstream out(args.output, std::ios::binary);
  out << text;
  out.close();
  if (!out) {
    const int error = errno;
    std::cerr << "rubble pack: output failure: cannot write " << args.output << ": " << std::strerror(error) << "\n";
    return exit_output_failure;
  }
  std::cerr << "rubble pack: wrote " << args.output << "; run it with: rubble run " << args.output << "\n";
  return exit_ok;
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
  pack->add_option("--shape", args->shape, "spheres, polyhedra (random convex, seed 001) or mix")
      ->check(CLI::IsMember({"spheres", "polyhedra", "mix"}));
  pack->add_option("--polyhedron-fraction", args->polyhedron_fraction, "mix: share of polyhedra by number")
      ->check(CLI::Range(0.0, 1.0));
  pack->add_option("--dmin", args->d_min, "Smallest diameter, m (circumscribed for polyhedra)")->check(CLI::PositiveNumber);
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
    if (args->distribution == "bins" && args->bins.empty()) throw CLI::ValidationError("--bins", "needed with --distribution bins");
    if (args->d_max < args->d_min && args->distribution != "monodisperse" && args->distribution != "bins") {
      throw CLI::ValidationError("--dmax", "expected dmax >= dmin");
    }
    const int code = pack_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
