#include "contact_detection/detection.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "contact_detection/narrow_phase_spheres.hpp"
#include "core/huge_pages.hpp"
#include "core/parallel.hpp"
#include "contact_detection/narrow_phase_polyhedra.hpp"

namespace rubble {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

/// Axis-aligned box around a grain in world coordinates.
struct Aabb {
  Vec3 lower;
  Vec3 upper;
};

bool overlap(const Aabb& a, const Aabb& b) {
  return (a.lower.array() <= b.upper.array()).all() && (b.lower.array() <= a.upper.array()).all();
}

/// World box of a box wall, inflated by the margin.
Aabb wall_box(const Model& model, const State& state, std::size_t wall, double margin) {
  const Box& box = model.boxes[static_cast<std::size_t>(model.shape_index[wall])];
  // Extent of a rotated box along each world axis: sum_j |R_ij| h_j.
  const Vec3 extent = state.orientation[wall].toRotationMatrix().cwiseAbs() * box.half_extents;
  return {state.position[wall] - extent - Vec3::Constant(margin),
          state.position[wall] + extent + Vec3::Constant(margin)};
}

using Cell = Eigen::Vector3i;

/// The broad phase's uniform grid of grains: cells hashed into 2^k buckets (about two per grain);
/// a bucket may hold grains of several cells, which the cell-range test tells apart. Buckets list
/// their grains (indices into the grain list) in increasing order.
struct GrainGrid {
  static constexpr int max_cells = 1 << 20;  ///< cells per axis at most
  Vec3 lower;                                ///< m, lower corner of the grid
  double cell = 0.0;                         ///< m, cell size
  std::size_t bucket_count = 64;             ///< a power of two
  std::vector<Cell> first_cell, last_cell;   ///< the cell range of each grain's box
  std::vector<std::uint32_t> bucket_start;   ///< bucket b's entries are [start[b], start[b+1])
  std::vector<std::uint32_t> bucket_grains;  ///< the entries: grain indices

  Cell cell_of(const Vec3& p) const {
    return ((p - lower) / cell).array().floor().cast<int>().cwiseMax(0).cwiseMin(max_cells - 1);
  }
  std::size_t bucket_of(const Cell& c) const {
    const std::uint64_t h = static_cast<std::uint64_t>(c.x()) * 73856093u ^
                            static_cast<std::uint64_t>(c.y()) * 19349663u ^
                            static_cast<std::uint64_t>(c.z()) * 83492791u;
    return static_cast<std::size_t>(h & (bucket_count - 1));
  }
  template <class Visit>
  void for_each_cell(std::size_t k, Visit&& visit) const {
    for (int x = first_cell[k].x(); x <= last_cell[k].x(); ++x)
      for (int y = first_cell[k].y(); y <= last_cell[k].y(); ++y)
        for (int z = first_cell[k].z(); z <= last_cell[k].z(); ++z) visit(Cell(x, y, z));
  }
};

/// Bins the grains' boxes. Cell size: the 90th-percentile bounding diameter plus the alert
/// distance, so most grains span at most 2 cells per axis (at most 8 cells) while a few large
/// grains (a 10:1 size ratio) span more cells instead of making every cell large. The domain is
/// capped to 2^20 cells per axis by growing the cell if needed. Buckets are filled by a counting
/// sort (no sort per step).
GrainGrid bin_grains(const Model& model, const std::vector<std::uint32_t>& grains, const std::vector<Aabb>& boxes,
                     double alert_distance) {
  GrainGrid grid;
  std::vector<double> radii(grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) radii[k] = model.bounding_radius[grains[k]];
  const std::size_t percentile = std::min(radii.size() - 1, radii.size() * 9 / 10);
  std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(percentile), radii.end());
  grid.lower = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 upper = -grid.lower;
  for (const Aabb& box : boxes) {
    grid.lower = grid.lower.cwiseMin(box.lower);
    upper = upper.cwiseMax(box.upper);
  }
  grid.cell = 2.0 * radii[percentile] + alert_distance;
  grid.cell = std::max(grid.cell, (upper - grid.lower).maxCoeff() / GrainGrid::max_cells);
  if (!(grid.cell > 0.0) || !std::isfinite(grid.cell)) {
    throw std::runtime_error("broad phase: non-finite grain positions");
  }
  while (grid.bucket_count < 2 * grains.size()) grid.bucket_count <<= 1;
  grid.first_cell.resize(grains.size());
  grid.last_cell.resize(grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    grid.first_cell[k] = grid.cell_of(boxes[k].lower);
    grid.last_cell[k] = grid.cell_of(boxes[k].upper);
  }
  grid.bucket_start.assign(grid.bucket_count + 1, 0);
  for (std::size_t k = 0; k < grains.size(); ++k)
    grid.for_each_cell(k, [&](const Cell& c) { ++grid.bucket_start[grid.bucket_of(c) + 1]; });
  for (std::size_t b = 0; b < grid.bucket_count; ++b) grid.bucket_start[b + 1] += grid.bucket_start[b];
  grid.bucket_grains.resize(grid.bucket_start.back());
  std::vector<std::uint32_t> fill(grid.bucket_start.begin(), grid.bucket_start.end() - 1);
  for (std::size_t k = 0; k < grains.size(); ++k) {
    grid.for_each_cell(
        k, [&](const Cell& c) { grid.bucket_grains[fill[grid.bucket_of(c)]++] = static_cast<std::uint32_t>(k); });
  }
  return grid;
}

/// Pairs (k, j > k) of overlapping grain boxes, each reported only from the cell holding the
/// lower corner of the two boxes' overlap. Grains are cut into fixed chunks whose pair lists are
/// concatenated in order, so the result is sorted and independent of the thread count.
std::vector<BodyPair> grain_pairs(const GrainGrid& grid, const std::vector<std::uint32_t>& grains,
                                  const std::vector<Aabb>& boxes) {
  constexpr std::size_t chunk = 256;
  const auto chunk_count = static_cast<std::ptrdiff_t>((grains.size() + chunk - 1) / chunk);
  std::vector<std::vector<BodyPair>> chunk_pairs(static_cast<std::size_t>(chunk_count));
#pragma omp parallel for schedule(dynamic, 1) if (static_cast <std::ptrdiff_t>(grains.size()) >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < chunk_count; ++i) {
    std::vector<BodyPair>& out = chunk_pairs[static_cast<std::size_t>(i)];
    const std::size_t first = static_cast<std::size_t>(i) * chunk;
    const std::size_t last = std::min(grains.size(), first + chunk);
    for (std::size_t k = first; k < last; ++k) {
      const std::size_t begin = out.size();
      grid.for_each_cell(k, [&](const Cell& c) {
        const std::size_t bucket = grid.bucket_of(c);
        for (std::uint32_t e = grid.bucket_start[bucket]; e < grid.bucket_start[bucket + 1]; ++e) {
          const std::uint32_t j = grid.bucket_grains[e];
          // A grain whose several cells hash to this bucket is listed once per cell, in a row.
          if (e > grid.bucket_start[bucket] && grid.bucket_grains[e - 1] == j) continue;
          if (j <= k || !overlap(boxes[k], boxes[j])) continue;
          if (grid.cell_of(boxes[k].lower.cwiseMax(boxes[j].lower)) != c) continue;  // owner cell only
          out.push_back({grains[k], grains[j]});
        }
      });
      std::sort(out.begin() + static_cast<std::ptrdiff_t>(begin), out.end());
    }
  }
  std::vector<BodyPair> pairs;
  for (const auto& part : chunk_pairs) pairs.insert(pairs.end(), part.begin(), part.end());
  return pairs;
}

/// Wall-grain pairs, sorted: plane walls as half-spaces against every grain's bounding sphere,
/// box walls by their world bounding box.
std::vector<BodyPair> wall_pairs(const Model& model, const State& state, const std::vector<std::uint32_t>& walls,
                                 const std::vector<std::uint32_t>& grains, const std::vector<Aabb>& boxes,
                                 double alert_distance, double margin) {
  std::vector<BodyPair> pairs;
  for (const std::uint32_t wall : walls) {
    if (model.shape_kind[wall] == ShapeKind::plane) {
      const Vec3 normal =
          state.orientation[wall] * model.planes[static_cast<std::size_t>(model.shape_index[wall])].normal;
      for (const std::uint32_t grain : grains) {
        const double gap = normal.dot(state.position[grain] - state.position[wall]) - model.bounding_radius[grain];
        if (gap < alert_distance) pairs.push_back({std::min(wall, grain), std::max(wall, grain)});
      }
      continue;
    }
    const Aabb box = wall_box(model, state, wall, margin);
    for (std::size_t k = 0; k < grains.size(); ++k) {
      if (overlap(box, boxes[k])) pairs.push_back({std::min(wall, grains[k]), std::max(wall, grains[k])});
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace

const Vec3* DetectionMemory::find(const BodyPair& pair) const {
  const auto it = std::lower_bound(pairs.begin(), pairs.end(), pair);
  if (it == pairs.end() || *it != pair) return nullptr;
  return &common_normals[static_cast<std::size_t>(it - pairs.begin())];
}

double resolve_alert_distance(const Model& model, const DetectionOptions& options) {
  if (options.alert_distance > 0.0) return options.alert_distance;
  double smallest = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (model.is_grain(b)) smallest = std::min(smallest, model.bounding_radius[b]);
  }
  return std::isfinite(smallest) ? 0.05 * smallest : 0.0;
}

std::vector<BodyPair> find_candidate_pairs(const Model& model, const State& state, double alert_distance) {
  // Grains go in a uniform grid; walls are few and tested against every grain.
  std::vector<std::uint32_t> grains;
  std::vector<std::uint32_t> walls;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    (model.is_grain(b) ? grains : walls).push_back(static_cast<std::uint32_t>(b));
  }
  const double margin = 0.5 * alert_distance;
  std::vector<Aabb> boxes(grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    const std::size_t b = grains[k];
    const Vec3 half = Vec3::Constant(model.bounding_radius[b] + margin);
    boxes[k] = {state.position[b] - half, state.position[b] + half};
  }
  std::vector<BodyPair> pairs;
  if (!grains.empty()) pairs = grain_pairs(bin_grains(model, grains, boxes, alert_distance), grains, boxes);
  // Grain pairs are sorted already (body ids of grains increase with k); merge the wall pairs in.
  const std::vector<BodyPair> walls_and_grains = wall_pairs(model, state, walls, grains, boxes, alert_distance, margin);
  const auto middle = static_cast<std::ptrdiff_t>(pairs.size());
  pairs.insert(pairs.end(), walls_and_grains.begin(), walls_and_grains.end());
  std::inplace_merge(pairs.begin(), pairs.begin() + middle, pairs.end());
  return pairs;
}

void collide_pair(const Model& model, const State& state, const BodyPair& pair, double alert_distance,
                  const DetectionMemory& memory, ContactList& contacts, Vec3& common_normal) {
  PolyhedronScratch scratch;
  collide_pair(model, state, pair, alert_distance, memory, contacts, common_normal, scratch);
}

void collide_pair(const Model& model, const State& state, const BodyPair& pair, double alert_distance,
                  const DetectionMemory& memory, ContactList& contacts, Vec3& common_normal,
                  PolyhedronScratch& scratch) {
  std::uint32_t a = pair.body_a;
  std::uint32_t b = pair.body_b;
  // Walls go first so the normal points from the wall into the grain.
  if (model.is_grain(a) && !model.is_grain(b)) std::swap(a, b);
  const ShapeKind kind_a = model.shape_kind[a];
  const ShapeKind kind_b = model.shape_kind[b];
  // Two bodies of infinite mass (walls, driven bodies) never interact: nothing could move either.
  if (model.is_fixed(a) && model.is_fixed(b)) return;
  const Vec3* previous = memory.find(pair);
  if (kind_a == ShapeKind::sphere && kind_b == ShapeKind::sphere) {
    collide_sphere_sphere(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::plane && kind_b == ShapeKind::sphere) {
    collide_plane_sphere(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::box && kind_b == ShapeKind::sphere) {
    collide_box_sphere(model, state, a, b, alert_distance, contacts);
  } else if (!model.is_grain(a) && !model.is_grain(b)) {
    return;  // two walls never interact
  } else if (kind_a == ShapeKind::polyhedron && kind_b == ShapeKind::polyhedron) {
    collide_polyhedron_polyhedron(model, state, a, b, alert_distance, previous, contacts, common_normal, scratch);
  } else if (kind_a == ShapeKind::sphere || kind_b == ShapeKind::sphere) {
    collide_sphere_polyhedron(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::plane) {
    collide_plane_polyhedron(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::box) {
    collide_box_polyhedron(model, state, a, b, alert_distance, previous, contacts, common_normal, scratch);
  } else {
    throw std::runtime_error("narrow phase: no contact routine for this pair of shapes");
  }
}

namespace {

/// Verlet list: a pair's bounding boxes approach by at most the two bodies' displacements, so
/// while every body has moved by less than margin / 2 the list holds every pair within alert.
bool pair_list_needs_rebuild(const Model& model, const State& state, const DetectionMemory& memory, double margin) {
  if (margin == 0.0 || memory.pair_list_margin != margin || memory.pair_list_positions.size() != state.body_count() ||
      memory.pair_order.size() != memory.pair_list.size()) {
    return true;
  }
  const double limit = 0.25 * margin * margin;
  for (std::size_t b = 0; b < state.body_count(); ++b) {
    if ((state.position[b] - memory.pair_list_positions[b]).squaredNorm() >= limit) return true;
  }
  // A turning wall (a driven one) sweeps its far parts by more than its displacement: a grain's
  // bounding sphere turns with it, a wall's plane or box does not, so its pairs are found afresh.
  for (const std::size_t b : model.driven_bodies) {
    if (!model.is_grain(b) && state.angular_velocity[b].squaredNorm() > 0.0) return true;
  }
  return false;
}

/// The broad phase into `memory`: the pair list within alert + margin, the positions it was
/// built at, and the pairs in their contacts' id order ((body_a, body_b) as collide_pair orders
/// them).
void rebuild_pair_list(const Model& model, const State& state, double alert, double margin, DetectionMemory& memory) {
  memory.pair_list = find_candidate_pairs(model, state, alert + margin);
  memory.pair_list_positions = state.position;
  memory.pair_list_margin = margin;
  const auto contact_bodies = [&](const BodyPair& pair) {
    return model.is_grain(pair.body_a) && !model.is_grain(pair.body_b) ? std::pair(pair.body_b, pair.body_a)
                                                                       : std::pair(pair.body_a, pair.body_b);
  };
  memory.pair_order.resize(memory.pair_list.size());
  for (std::size_t k = 0; k < memory.pair_order.size(); ++k) memory.pair_order[k] = static_cast<std::uint32_t>(k);
  std::sort(memory.pair_order.begin(), memory.pair_order.end(), [&](std::uint32_t x, std::uint32_t y) {
    return contact_bodies(memory.pair_list[x]) < contact_bodies(memory.pair_list[y]);
  });
}

/// Contacts in id order (a lambda, not a function, so the sorts inline it).
constexpr auto contact_id_less = [](const Contact& x, const Contact& y) { return x.id < y.id; };

/// The narrow phase of every listed pair. The pairs are collided in waves of `wave` pairs, in the
/// order of their contacts' ids (memory.pair_order): within a wave each pair writes and sorts its
/// own slot (in parallel), then the wave's lists are appended to the result in that order, so the
/// list comes out sorted by id and the same for any thread count, without a serial sort of the
/// contacts (walls numbered after the grains made every step's list need one). Only one wave's
/// lists live beside the result (at 1e5 spheres, one list per pair, all alive at once, were a
/// third of the run's peak memory); the slots keep their capacity from wave to wave, so a steady
/// run allocates almost nothing here. The pairs that touched and their common-plane normals go
/// to `next` (in id order).
ContactList collide_listed_pairs(const Model& model, const State& state, double alert, const DetectionMemory& memory,
                                 DetectionMemory& next) {
  const std::vector<BodyPair>& pairs = memory.pair_list;
  const std::vector<std::uint32_t>& order = memory.pair_order;
  constexpr std::size_t wave = 4096;
  std::vector<ContactList> per_pair(std::min(wave, pairs.size()));
  std::vector<Vec3> normals(per_pair.size());
  ContactList contacts;
  // Last step's count plus 1/8: the list is rarely copied while it grows. Reserved pages that are
  // never written are not resident (a list this large is a fresh mapping).
  contacts.reserve(memory.contact_count + memory.contact_count / 8);
  // Huge pages over the part last step's count will fill, not the reserve beyond it, which stays
  // out of memory unless written (core/huge_pages.hpp).
  advise_huge_pages(contacts.data(), memory.contact_count * sizeof(Contact));
  for (std::size_t first = 0; first < pairs.size(); first += wave) {
    const std::size_t count = std::min(wave, pairs.size() - first);
    const auto count_signed = static_cast<std::ptrdiff_t>(count);
    std::fill(normals.begin(), normals.end(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
#pragma omp parallel if (count_signed >= min_parallel_items / 4)
    {
      // Each thread's own working space for the polyhedral narrow phase: its buffers grow on the
      // first pairs and are reused by the rest of the wave (no allocation per pair).
      PolyhedronScratch scratch;
#pragma omp for schedule(dynamic, 32)
      for (std::ptrdiff_t p = 0; p < count_signed; ++p) {
        const auto k = static_cast<std::size_t>(p);
        ContactList& list = per_pair[k];
        collide_pair(model, state, pairs[order[first + k]], alert, memory, list, normals[k], scratch);
        // (stable_sort allocates a buffer even for a sorted list of two)
        if (!std::is_sorted(list.begin(), list.end(), contact_id_less)) {
          std::stable_sort(list.begin(), list.end(), contact_id_less);
        }
      }
    }
    std::size_t found = 0;
    for (std::size_t k = 0; k < count; ++k) found += per_pair[k].size();
    if (contacts.size() + found > contacts.capacity()) {
      // Grow by a quarter, not the default doubling: the old and new buffers coexist while copying.
      contacts.reserve(std::max(contacts.size() + found, contacts.capacity() + contacts.capacity() / 4));
    }
    for (std::size_t k = 0; k < count; ++k) {
      contacts.insert(contacts.end(), per_pair[k].begin(), per_pair[k].end());
      if (!per_pair[k].empty() && !std::isnan(normals[k].x())) {
        next.pairs.push_back(pairs[order[first + k]]);
        next.common_normals.push_back(normals[k]);
      }
      per_pair[k].clear();
    }
  }
  return contacts;
}

/// The common-plane memory is searched by pair (DetectionMemory::find): back to pair order.
void sort_common_normals_by_pair(DetectionMemory& next) {
  if (std::is_sorted(next.pairs.begin(), next.pairs.end())) return;
  std::vector<std::size_t> by_pair(next.pairs.size());
  for (std::size_t i = 0; i < by_pair.size(); ++i) by_pair[i] = i;
  std::sort(by_pair.begin(), by_pair.end(),
            [&](std::size_t x, std::size_t y) { return next.pairs[x] < next.pairs[y]; });
  std::vector<BodyPair> sorted_pairs(by_pair.size());
  std::vector<Vec3> sorted_normals(by_pair.size());
  for (std::size_t i = 0; i < by_pair.size(); ++i) {
    sorted_pairs[i] = next.pairs[by_pair[i]];
    sorted_normals[i] = next.common_normals[by_pair[i]];
  }
  next.pairs = std::move(sorted_pairs);
  next.common_normals = std::move(sorted_normals);
}

}  // namespace

ContactList detect_contacts(const Model& model, const State& state, const DetectionOptions& options,
                            DetectionMemory& memory, DetectionStats* stats) {
  const double alert = resolve_alert_distance(model, options);
  auto start = Clock::now();
  const double margin = options.pair_list_margin < 0.0 ? alert : options.pair_list_margin;
  const bool rebuild = pair_list_needs_rebuild(model, state, memory, margin);
  if (rebuild) rebuild_pair_list(model, state, alert, margin, memory);
  const double broad_seconds = seconds_since(start);

  start = Clock::now();
  DetectionMemory next;
  ContactList contacts = collide_listed_pairs(model, state, alert, memory, next);
  sort_common_normals_by_pair(next);
  // Holds when every narrow-phase routine writes its contacts as (a, b) in collide_pair's order;
  // warm start (carry_impulses) merges on this order, so a violation must not pass silently.
  if (!std::is_sorted(contacts.begin(), contacts.end(), contact_id_less)) {
    throw std::logic_error("detect_contacts: a narrow-phase routine wrote contact ids out of its pair's (a, b) order");
  }
  next.contact_count = contacts.size();
  if (stats) stats->candidate_pairs = memory.pair_list.size();
  next.pair_list = std::move(memory.pair_list);
  next.pair_list_positions = std::move(memory.pair_list_positions);
  next.pair_order = std::move(memory.pair_order);
  next.pair_list_margin = memory.pair_list_margin;
  memory = std::move(next);
  if (stats) {
    stats->pair_list_rebuilt = rebuild;
    stats->broad_phase_seconds = broad_seconds;
    stats->narrow_phase_seconds = seconds_since(start);
  }
  return contacts;
}

std::vector<CarriedImpulse> impulses_to_carry(const ContactList& previous) {
  std::vector<CarriedImpulse> carried(previous.size());
  for (std::size_t k = 0; k < previous.size(); ++k) {
    // The world impulse is what the frames rotate between; computed here exactly as the
    // expression frame^T (old frame * old impulse) would, so the carried value is the same to the bit.
    carried[k] = {previous[k].id, previous[k].frame * previous[k].impulse};
  }
  return carried;
}

void carry_impulses(const std::vector<CarriedImpulse>& previous, ContactList& current) {
  auto old = previous.begin();
  for (Contact& contact : current) {
    while (old != previous.end() && old->id < contact.id) ++old;
    if (old == previous.end()) break;
    if (old->id == contact.id) {
      // Same impulse in the world, expressed in the new frame.
      contact.impulse = contact.frame.transpose() * old->world_impulse;
    }
  }
}

void carry_impulses(const ContactList& previous, ContactList& current) {
  carry_impulses(impulses_to_carry(previous), current);
}

std::vector<Vec3> angular_impulses_to_carry(const ContactList& previous) {
  std::vector<Vec3> carried(previous.size());
  for (std::size_t k = 0; k < previous.size(); ++k) carried[k] = previous[k].frame * previous[k].angular_impulse;
  return carried;
}

void carry_angular_impulses(const std::vector<CarriedImpulse>& previous, const std::vector<Vec3>& previous_angular,
                            ContactList& current) {
  std::size_t old = 0;
  for (Contact& contact : current) {
    while (old < previous.size() && previous[old].id < contact.id) ++old;
    if (old == previous.size()) break;
    if (previous[old].id == contact.id) contact.angular_impulse = contact.frame.transpose() * previous_angular[old];
  }
}

}  // namespace rubble
