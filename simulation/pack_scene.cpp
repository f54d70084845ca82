// The scene text `rubble pack` writes (pack_scene.hpp). Shared by the CLI and the Python module.
#include "simulation/pack_scene.hpp"

#include <array>
#include <cmath>
#include <fmt/format.h>
#include <sstream>
#include <stdexcept>
#include <initializer_list>
#include <string>

namespace rubble {
namespace {

std::string number(double x) { return fmt::format("{}", x); }

/// The size keys of a generator from the arguments.
std::string size_keys(const PackOptions& a) {
  if (a.distribution == "monodisperse") {
    return fmt::format("distribution = \"monodisperse\"\nradius = {}\n", number(0.5 * a.d_max));
  }
  if (a.distribution == "bins") {
    std::string list;
    std::stringstream in(a.bins);
    std::string item;
    while (std::getline(in, item, ',')) {
      const auto colon = item.find(':');
      if (colon == std::string::npos)
        throw std::invalid_argument("--bins: expected DIAMETER:FRACTION pairs, got \"" + item + "\"");
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

std::string shape_keys(const PackOptions& a) {
  if (a.shape == "polyhedra") return "shape = \"polyhedron\"\n";
  if (a.shape == "mix")
    return fmt::format("shape = \"mix\"\npolyhedron_fraction = {}\n", number(a.polyhedron_fraction));
  return "shape = \"sphere\"\n";
}

}  // namespace

void check_pack_options(const PackOptions& a) {
  const auto one_of = [](const std::string& flag, const std::string& value,
                         std::initializer_list<const char*> allowed) {
    std::string list;
    for (const char* item : allowed) {
      if (value == item) return;
      list += fmt::format("{}{}", list.empty() ? "" : ", ", item);
    }
    throw std::invalid_argument(fmt::format("{}: expected one of {}, got \"{}\"", flag, list, value));
  };
  one_of("kind", a.kind, {"cubic-grid", "cloud", "box"});
  one_of("--shape", a.shape, {"spheres", "polyhedra", "mix"});
  one_of("--distribution", a.distribution, {"volume-fraction", "uniform", "monodisperse", "bins"});
  one_of("--bin-fractions", a.bin_fractions, {"volume", "number"});
  if (a.count < 1) throw std::invalid_argument("--n: expected a number of grains >= 1");
  if (a.distribution == "bins" && a.bins.empty())
    throw std::invalid_argument("--bins: needed with --distribution bins");
  if (a.d_max < a.d_min && a.distribution != "monodisperse" && a.distribution != "bins") {
    throw std::invalid_argument("--dmax: expected dmax >= dmin");
  }
}

std::string pack_command_line(const PackOptions& a) {
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

std::string pack_scene_text(const PackOptions& a) {
  check_pack_options(a);
  std::ostringstream out;
  const bool box = a.kind == "box";
  const std::string name = a.name.empty() ? fmt::format("{}-{}-{}", a.kind, a.count, a.shape) : a.name;
  out << "# rubble scene file written by rubble pack; reference: docs/scene-file.md. Regenerate with:\n# "
      << pack_command_line(a) << "\n";
  out << "name = \"" << name << "\"\nseed = " << a.seed << "\n\n";
  // Time: dt from the scene, until at rest; the end time caps the run.
  double end_time = a.end_time;
  if (!(end_time > 0.0)) {
    // Accretion: 7 characteristic times 1/sqrt(G rho) (the study's plateau starts near 4.4 of
    // them, 125 min); deposit: 20 fall times over the box height.
    end_time = box ? 20.0 * std::sqrt(2.0 * 10.0 * a.d_max / a.g)
                   : std::round(7.0 / std::sqrt(units::gravitational_constant * a.density));
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
      throw std::invalid_argument(
          fmt::format("--n {} is not a cube k^3 (the cubic grid has n = k^3 grains; nearest: {} or {})", a.count,
                      k * k * k, (k + 1) * (k + 1) * (k + 1)));
    }
    out << "[[generators]]\ntype = \"cubic_grid\"\ncells_per_side = " << k << "\ncell_size = " << number(a.d_max)
        << "\n";
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
    for (const auto& [px, py, nx, ny] :
         {std::array<double, 4>{-h, 0, 1, 0}, {h, 0, -1, 0}, {0, -h, 0, 1}, {0, h, 0, -1}}) {
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

}  // namespace rubble
