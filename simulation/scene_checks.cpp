// The checks of a scene as a whole, after every section is read and before its bodies are made:
// contact laws for every pair of materials that can touch, walls with an inside, grains inside
// the walls and not interpenetrating (docs/scene-file.md).
#include <algorithm>

#include "simulation/scene_parser.hpp"

namespace rubble::scene_detail {

void check_contact_law_coverage(const SceneDraft& draft) {
  if (draft.default_law) return;
  const auto& materials = draft.scene.model.materials;
  const int n = static_cast<int>(materials.size());
  std::vector<bool> grain_material(static_cast<std::size_t>(n), false);
  std::vector<bool> wall_material(static_cast<std::size_t>(n), false);
  for (const GrainSpec& g : draft.grains) grain_material[static_cast<std::size_t>(g.material)] = true;
  for (const GrainSpec& g : draft.inflow_grains) grain_material[static_cast<std::size_t>(g.material)] = true;
  for (const WallSpec& w : draft.walls) wall_material[static_cast<std::size_t>(w.material)] = true;
  for (int a = 0; a < n; ++a) {
    if (!grain_material[static_cast<std::size_t>(a)]) continue;
    for (int b = 0; b < n; ++b) {
      if (!grain_material[static_cast<std::size_t>(b)] && !wall_material[static_cast<std::size_t>(b)]) continue;
      if (draft.law_defined[draft.scene.model.contact_laws.index(a, b)]) continue;
      const std::string& name_a = materials[static_cast<std::size_t>(a)].name;
      const std::string& name_b = materials[static_cast<std::size_t>(b)].name;
      draft.root.fail(draft.root.get("contact_laws"), "contact_laws",
                      "no contact law for materials \"" + name_a + "\" and \"" + name_b +
                          "\", which can touch: expected a [[contact_laws]] entry with materials = [\"" + name_a +
                          "\", \"" + name_b + "\"] (or a [default_contact_law])");
    }
  }
}

void check_rotation_resistance_shapes(const SceneDraft& draft) {
  const Model& model = draft.scene.model;
  const std::size_t n = model.materials.size();
  std::vector<bool> polyhedra(n, false), touches(n, false);
  for (const auto* grains : {&draft.grains, &draft.inflow_grains}) {  // the [[inflow]] grains touch too
    for (const GrainSpec& g : *grains) {
      touches[static_cast<std::size_t>(g.material)] = true;
      if (g.is_polyhedron()) polyhedra[static_cast<std::size_t>(g.material)] = true;
    }
  }
  for (const WallSpec& w : draft.walls) touches[static_cast<std::size_t>(w.material)] = true;
  // The polyhedron material of pair (a, b) whose law resists rotation, or -1.
  auto polyhedron_material = [&](int a, int b) {
    if (!model.contact_laws.get(a, b).resists_rotation()) return -1;
    const auto ua = static_cast<std::size_t>(a), ub = static_cast<std::size_t>(b);
    if (polyhedra[ua] && touches[ub]) return a;
    if (polyhedra[ub] && touches[ua]) return b;
    return -1;
  };
  auto refuse = [&](const TableReader& entry, int material) {
    const std::string_view key = entry.has("rolling_friction") ? "rolling_friction" : "twisting_friction";
    entry.fail_key(key, "rolling and twisting resistance act on sphere contacts only, and material \"" +
                            model.materials[static_cast<std::size_t>(material)].name +
                            "\" is used by polyhedron grains: expected 0 for a pair with a polyhedron material (a "
                            "polyhedron's shape resists rolling through the points of its faces; docs/scene-file.md, "
                            "\"Rolling and twisting resistance\")");
  };
  for (const TableReader& entry : draft.root.tables("contact_laws")) {
    const auto* pair = entry.get("materials")->as_array();
    const int a = draft.material_ids.at(std::string(pair->get(0)->as_string()->get()));
    const int b = draft.material_ids.at(std::string(pair->get(1)->as_string()->get()));
    if (const int material = polyhedron_material(a, b); material >= 0) refuse(entry, material);
  }
  if (!draft.default_law || !draft.default_law->resists_rotation()) return;
  for (int a = 0; a < static_cast<int>(n); ++a) {
    for (int b = 0; b < static_cast<int>(n); ++b) {
      if (draft.law_defined[model.contact_laws.index(a, b)]) continue;
      if (const int material = polyhedron_material(a, b); material >= 0) {
        refuse(*draft.root.optional_table("default_contact_law"), material);
      }
    }
  }
}

/// (With grains present, any other empty intersection of half-spaces is caught by the grain check.)
void check_walls_have_an_inside(const SceneDraft& draft) {
  const auto& walls = draft.walls;
  for (std::size_t i = 0; i < walls.size(); ++i) {
    if (!walls[i].is_plane) continue;
    for (std::size_t j = i + 1; j < walls.size(); ++j) {
      if (!walls[j].is_plane) continue;
      const Vec3& n = walls[i].normal;
      if (n.dot(walls[j].normal) > -1.0 + 1e-12) continue;
      // Inside of i: n.(x - p_i) >= 0; inside of j: n.(x - p_j) <= 0 (its normal is -n).
      const double width = n.dot(walls[j].position - walls[i].position);
      if (width <= 0.0) {
        draft.root.fail(walls[j].node, walls[j].path,
                        "this plane and " + walls[i].path + " face away from each other with no space between them (" +
                            "distance " + show_short(width) +
                            " m along the normal): expected their normals to point into a common inside");
      }
    }
  }
}

namespace {

/// A polyhedron is checked by its vertices: none may be behind a plane or inside a box.
void check_polyhedron_inside_wall(const SceneDraft& draft, const WallSpec& wall, const Mat3& to_body,
                                  const GrainSpec& grain) {
  const double tolerance = allowed_initial_overlap * grain.radius;
  const Mat3 rotation = grain.orientation.toRotationMatrix();
  for (const Vec3& vertex : grain.polyhedron->vertices) {
    const Vec3 x = grain.position + rotation * vertex;
    const bool bad = wall.is_plane
                         ? wall.normal.dot(x - wall.position) < -tolerance
                         : ((to_body * (x - wall.position)).cwiseAbs() - wall.half_extents).maxCoeff() < -tolerance;
    if (bad) {
      draft.root.fail(grain.origin.node, grain_key(grain.origin),
                      grain_label(grain.origin) + " (a polyhedron centred at " + show_vec3(grain.position) +
                          ") has a vertex at " + show_vec3(x) +
                          (wall.is_plane ? " behind plane wall " : " inside box wall ") + wall.path +
                          ": expected every grain entirely on the inner side of the walls");
    }
  }
}

void check_sphere_inside_wall(const SceneDraft& draft, const WallSpec& wall, const Mat3& to_body,
                              const GrainSpec& grain) {
  const double tolerance = allowed_initial_overlap * grain.radius;
  if (wall.is_plane) {
    const double distance = wall.normal.dot(grain.position - wall.position);
    if (distance < grain.radius - tolerance) {
      const std::string where = distance < 0.0 ? "has its centre behind" : "crosses";
      draft.root.fail(grain.origin.node, grain_key(grain.origin),
                      grain_label(grain.origin) + " at " + show_vec3(grain.position) + " (radius " +
                          show_short(grain.radius) + " m) " + where + " plane wall " + wall.path +
                          " (signed distance " + show_short(distance) +
                          " m): expected every grain entirely on the side its normal points to");
    }
  } else {
    const Vec3 local = to_body * (grain.position - wall.position);
    const Vec3 outside = (local.cwiseAbs() - wall.half_extents).cwiseMax(0.0);
    if (outside.norm() < grain.radius - tolerance) {
      draft.root.fail(grain.origin.node, grain_key(grain.origin),
                      grain_label(grain.origin) + " at " + show_vec3(grain.position) + " (radius " +
                          show_short(grain.radius) + " m) overlaps box wall " + wall.path +
                          ": expected grains outside box walls");
    }
  }
}

}  // namespace

void check_grains_inside_walls(const SceneDraft& draft) {
  for (const WallSpec& wall : draft.walls) {
    const Mat3 to_body = wall.orientation.toRotationMatrix().transpose();
    for (const GrainSpec& grain : draft.grains) {
      if (grain.polyhedron) {
        check_polyhedron_inside_wall(draft, wall, to_body, grain);
      } else {
        check_sphere_inside_wall(draft, wall, to_body, grain);
      }
    }
  }
}

/// Grid search (cell = largest sphere diameter) for pairs of spheres overlapping by more than the
/// allowed fraction of the smaller radius: O(N log N), about a second for 10^6 spheres.
/// Polyhedra are not checked: their bounding spheres may overlap without the solids touching,
/// and generators never make overlapping grains.
void check_grains_do_not_overlap(const SceneDraft& draft) {
  const auto& grains = draft.grains;
  double radius_max = 0.0;
  for (const GrainSpec& g : grains) {
    if (!g.polyhedron) radius_max = std::max(radius_max, g.radius);
  }
  const double cell = 2.0 * radius_max;
  struct Entry {
    std::int64_t x, y, z;
    std::size_t grain;
  };
  std::vector<Entry> entries;
  for (std::size_t i = 0; i < grains.size(); ++i) {
    if (grains[i].polyhedron) continue;
    const auto cell_of = [&](int axis) {
      return static_cast<std::int64_t>(std::clamp(std::floor(grains[i].position[axis] / cell), -1e15, 1e15));
    };
    entries.push_back({cell_of(0), cell_of(1), cell_of(2), i});
  }
  // Lexicographic (x, y, z) order: the three cells (x, y, z - 1 .. z + 1) of a column are
  // contiguous, so each grain needs nine searches, not 27.
  const auto before = [](const Entry& a, const Entry& b) {
    if (a.x != b.x) return a.x < b.x;
    if (a.y != b.y) return a.y < b.y;
    if (a.z != b.z) return a.z < b.z;
    return a.grain < b.grain;
  };
  std::sort(entries.begin(), entries.end(), before);
  for (const Entry& e : entries) {
    const GrainSpec& a = grains[e.grain];
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const Entry first{e.x + dx, e.y + dy, e.z - 1, 0};
        auto it = std::lower_bound(entries.begin(), entries.end(), first, before);
        for (; it != entries.end() && it->x == first.x && it->y == first.y && it->z <= e.z + 1; ++it) {
          if (it->grain <= e.grain) continue;
          const GrainSpec& b = grains[it->grain];
          const double overlap = a.radius + b.radius - (a.position - b.position).norm();
          if (overlap > allowed_initial_overlap * std::min(a.radius, b.radius)) {
            draft.root.fail(b.origin.node, grain_key(b.origin),
                            grain_label(b.origin) + " overlaps " + grain_name(a.origin) + " by " + show_short(overlap) +
                                " m: expected grains not to interpenetrate at the start (at most " +
                                show(100 * allowed_initial_overlap) + "% of the smaller radius)");
          }
        }
      }
    }
  }
}

}  // namespace rubble::scene_detail
