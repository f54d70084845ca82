#include "contact_detection/detection.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "contact_detection/narrow_phase_spheres.hpp"
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

// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
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
  if (!grains.empty()) {
    // Cell size: the 90th-percentile bounding diameter plus the alert distance, so most grains
    // span at most 2 cells per axis (at most 8 cells) while a few large grains (a 10:1 size
    // ratio) span more cells instead of making every cell large. The domain is capped to 2^20
    // cells per axis by growing the cell if needed.
    std::vector<double> radii(grains.size());
    for (std::size_t k = 0; k < grains.size(); ++k) radii[k] = model.bounding_radius[grains[k]];
    const std::size_t percentile = std::min(radii.size() - 1, radii.size() * 9 / 10);
    std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(percentile), radii.end());
    Vec3 lower = Vec3::Constant(std::numeric_limits<double>::infinity());
    Vec3 upper = -lower;
    for (const Aabb& box : boxes) {
      lower = lower.cwiseMin(box.lower);
      upper = upper.cwiseMax(box.upper);
    }
    constexpr int max_cells = 1 << 20;
    double cell = 2.0 * radii[percentile] + alert_distance;
    cell = std::max(cell, (upper - lower).maxCoeff() / max_cells);
    if (!(cell > 0.0) || !std::isfinite(cell)) throw std::runtime_error("broad phase: non-finite grain positions");

    using Cell = Eigen::Vector3i;
    auto cell_of = [&](const Vec3& p) -> Cell {
      return ((p - lower) / cell).array().floor().cast<int>().cwiseMax(0).cwiseMin(max_cells - 1);
    };
    // Spatial hash of the cells into a table of 2^k buckets (about two per grain); a bucket may
    // hold grains of several cells, which the cell-range test below tells apart.
    std::size_t bucket_count = 64;
    while (bucket_count < 2 * grains.size()) bucket_count <<= 1;
    auto bucket_of = [&](const Cell& c) {
      const std::uint64_t h = static_cast<std::uint64_t>(c.x()) * 73856093u ^
                              static_cast<std::uint64_t>(c.y()) * 19349663u ^
                              static_cast<std::uint64_t>(c.z()) * 83492791u;
      return static_cast<std::size_t>(h & (bucket_count - 1));
    };
    std::vector<Cell> first_cell(grains.size()), last_cell(grains.size());
    for (std::size_t k = 0; k < grains.size(); ++k) {
      first_cell[k] = cell_of(boxes[k].lower);
      last_cell[k] = cell_of(boxes[k].upper);
    }
    auto for_each_cell = [&](std::size_t k, auto&& visit) {
      for (int x = first_cell[k].x(); x <= last_cell[k].x(); ++x)
        for (int y = first_cell[k].y(); y <= last_cell[k].y(); ++y)
          for (int z = first_cell[k].z(); z <= last_cell[k].z(); ++z) visit(Cell(x, y, z));
    };
    // Counting sort of (bucket, grain) entries: buckets list their grains in increasing order.
    std::vector<std::uint32_t> bucket_start(bucket_count + 1, 0);
    for (std::size_t k = 0; k < grains.size(); ++k)
      for_each_cell(k, [&](const Cell& c) { ++bucket_start[bucket_of(c) + 1]; });
    for (std::size_t b = 0; b < bucket_count; ++b) bucket_start[b + 1] += bucket_start[b];
    std::vector<std::uint32_t> bucket_grains(bucket_start.back());
    {
      std::vector<std::uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
      for (std::size_t k = 0; k < grains.size(); ++k) {
        for_each_cell(k, [&](const Cell& c) { bucket_grains[fill[bucket_of(c)]++] = static_cast<std::uint32_t>(k); });
      }
    }

    // Pairs (k, j > k) of overlapping boxes, each reported only from the cell holding the lower
    // corner of the two boxes' overlap. Grains are cut into fixed chunks whose pair lists are
    // concatenated in order, so the result is sorted and independent of the thread count.
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
        for_each_cell(k, [&](const Cell& c) {
          const std::size_t bucket = bucket_of(c);
          for (std::uint32_t e = bucket_start[bucket]; e < bucket_start[bucket + 1]; ++e) {
            const std::uint32_t j = bucket_grains[e];
            // A grain whose several cells hash to this bucket is listed once per cell, in a row.
            if (e > bucket_start[bucket] && bucket_grains[e - 1] == j) continue;
            if (j <= k || !overlap(boxes[k], boxes[j])) continue;
            if (cell_of(boxes[k].lower.cwiseMax(boxes[j].lower)) != c) continue;  // owner cell only
            out.push_back({grains[k], grains[j]});
          }
        });
        std::sort(out.begin() + static_cast<std::ptrdiff_t>(begin), out.end());
      }
    }
    for (const auto& part : chunk_pairs) pairs.insert(pairs.end(), part.begin(), part.end());
  }

  std::vector<BodyPair> wall_pairs;
  for (const std::uint32_t wall : walls) {
    if (model.shape_kind[wall] == ShapeKind::plane) {
      // Half-space test: only grains whose bounding sphere comes within the alert distance.
      const Vec3 normal =
          state.orientation[wall] * model.planes[static_cast<std::size_t>(model.shape_index[wall])].normal;
      for (const std::uint32_t grain : grains) {
        const double gap = normal.dot(state.position[grain] - state.position[wall]) - model.bounding_radius[grain];
        if (gap < alert_distance) wall_pairs.push_back({std::min(wall, grain), std::max(wall, grain)});
      }
      continue;
    }
    const Aabb box = wall_box(model, state, wall, margin);
    for (std::size_t k = 0; k < grains.size(); ++k) {
      if (overlap(box, boxes[k])) wall_pairs.push_back({std::min(wall, grains[k]), std::max(wall, grains[k])});
    }
  }
  // Grain pairs are sorted already (body ids of grains increase with k); merge the wall pairs in.
  std::sort(wall_pairs.begin(), wall_pairs.end());
  const auto middle = static_cast<std::ptrdiff_t>(pairs.size());
  pairs.insert(pairs.end(), wall_pairs.begin(), wall_pairs.end());
  std::inplace_merge(pairs.begin(), pairs.begin() + middle, pairs.end());
  return pairs;
}

void collide_pair(const Model& model, const State& state, const BodyPair& pair, double alert_distance,
                  const DetectionMemory& memory, ContactList& contacts, Vec3& common_normal) {
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
    collide_polyhedron_polyhedron(model, state, a, b, alert_distance, previous, contacts, common_normal);
  } else if (kind_a == ShapeKind::sphere || kind_b == ShapeKind::sphere) {
    collide_sphere_polyhedron(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::plane) {
    collide_plane_polyhedron(model, state, a, b, alert_distance, contacts);
  } else if (kind_a == ShapeKind::box) {
    collide_box_polyhedron(model, state, a, b, alert_distance, previous, contacts, common_normal);
  } else {
    throw std::runtime_error("narrow phase: no contact routine for this pair of shapes");
  }
}

// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
ContactList detect_contacts(const Model& model, const State& state, const DetectionOptions& options,
                            DetectionMemory& memory, DetectionStats* stats) {
  const double alert = resolve_alert_distance(model, options);
  auto start = Clock::now();
  const double margin = options.pair_list_margin < 0.0 ? alert : options.pair_list_margin;
  // Verlet list: a pair's bounding boxes approach by at most the two bodies' displacements, so
  // while every body has moved by less than margin / 2 the list holds every pair within alert.
  bool rebuild = margin == 0.0 || memory.pair_list_margin != margin ||
                 memory.pair_list_positions.size() != state.body_count() ||
                 memory.pair_order.size() != memory.pair_list.size();
  if (!rebuild) {
    const double limit = 0.25 * margin * margin;
    for (std::size_t b = 0; b < state.body_count() && !rebuild; ++b) {
      rebuild = (state.position[b] - memory.pair_list_positions[b]).squaredNorm() >= limit;
    }
    // A turning wall (a driven one) sweeps its far parts by more than its displacement: a grain's
    // bounding sphere turns with it, a wall's plane or box does not, so its pairs are found afresh.
    for (std::size_t k = 0; k < model.driven_bodies.size() && !rebuild; ++k) {
      const std::size_t b = model.driven_bodies[k];
      rebuild = !model.is_grain(b) && state.angular_velocity[b].squaredNorm() > 0.0;
    }
  }
  if (rebuild) {
    memory.pair_list = find_candidate_pairs(model, state, alert + margin);
    memory.pair_list_positions = state.position;
    memory.pair_list_margin = margin;
    // The pairs in their contacts' id order: (body_a, body_b) as collide_pair orders them.
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
  const std::vector<BodyPair>& pairs = memory.pair_list;
  const double broad_seconds = seconds_since(start);

  start = Clock::now();
  // The pairs are collided in waves of `wave` pairs, in the order of their contacts' ids
  // (memory.pair_order): within a wave each pair writes and sorts its own slot (in parallel), then
  // the wave's lists are appended to `contacts` in that order, so the list comes out sorted by id
  // and the same for any thread count, without a serial sort of the contacts (walls numbered
  // after the grains made every step's list need one). Only one wave's lists live beside the
  // result (at 1e5 spheres, one list per pair, all alive at once, were a third of the run's peak
  // memory); the slots keep their capacity from wave to wave, so a steady run allocates almost
  // nothing here.
  const auto by_id = [](const Contact& x, const Contact& y) { return x.id < y.id; };
  const std::vector<std::uint32_t>& order = memory.pair_order;
  constexpr std::size_t wave = 4096;
  std::vector<ContactList> per_pair(std::min(wave, pairs.size()));
  std::vector<Vec3> normals(per_pair.size());
  ContactList contacts;
  // Last step's count plus 1/8: the list is rarely copied while it grows. Reserved pages that are
  // never written are not resident (a list this large is a fresh mapping).
  contacts.reserve(memory.contact_count + memory.contact_count / 8);
  DetectionMemory next;
  for (std::size_t first = 0; first < pairs.size(); first += wave) {
    const std::size_t count = std::min(wave, pairs.size() - first);
    const auto count_signed = static_cast<std::ptrdiff_t>(count);
    std::fill(normals.begin(), normals.end(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
#pragma omp parallel for schedule(dynamic, 32) if (count_signed >= min_parallel_items / 4)
    for (std::ptrdiff_t p = 0; p < count_signed; ++p) {
      const auto k = static_cast<std::size_t>(p);
      ContactList& list = per_pair[k];
      collide_pair(model, state, pairs[order[first + k]], alert, memory, list, normals[k]);
      // (stable_sort allocates a buffer even for a sorted list of two)
      if (!std::is_sorted(list.begin(), list.end(), by_id)) std::stable_sort(list.begin(), list.end(), by_id);
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
  // The common-plane memory is searched by pair (DetectionMemory::find): back to pair order.
  if (!std::is_sorted(next.pairs.begin(), next.pairs.end())) {
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
  // Holds when every narrow-phase routine writes its contacts as (a, b) in collide_pair's order;
  // warm start (carry_impulses) merges on this order, so a violation must not pass silently.
  if (!std::is_sorted(contacts.begin(), contacts.end(), by_id)) {
    throw std::logic_error("detect_contacts: a narrow-phase routine wrote contact ids out of its pair's (a, b) order");
  }
  next.contact_count = contacts.size();
  if (stats) stats->candidate_pairs = pairs.size();
  next.pair_list = std::move(memory.pair_list);  // `pairs` is not used below
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

}  // namespace rubble
