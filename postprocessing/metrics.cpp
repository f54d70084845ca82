#include "postprocessing/metrics.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <utility>

#include "gravity/gravity.hpp"
#include "preprocessing/random_polyhedron.hpp"

namespace rubble {
namespace {

/// Volume of the intersection of a ball of radius r at distance d from the centre of a ball of
/// radius big_r (the lens of two spheres; e.g. Weisstein, "Sphere-Sphere Intersection"):
/// V = pi (R + r - d)^2 (d^2 + 2 d r - 3 r^2 + 2 d R + 6 r R - 3 R^2) / (12 d).
double ball_intersection_volume(double big_r, double r, double d) {
  if (d >= big_r + r) return 0.0;
  if (d <= std::abs(big_r - r)) {
    const double small = std::min(big_r, r);
    return 4.0 / 3.0 * std::numbers::pi * small * small * small;
  }
  const double a = big_r + r - d;
  return std::numbers::pi * a * a *
         (d * d + 2.0 * d * r - 3.0 * r * r + 2.0 * d * big_r + 6.0 * r * big_r - 3.0 * big_r * big_r) / (12.0 * d);
}

bool carries_force(const Contact& contact, const ContactMetricsOptions& options) {
  return contact.impulse.x() > options.impulse_threshold;
}

/// Distinct body pairs (lower id first) touching through at least one force-bearing point, sorted.
std::vector<std::pair<std::uint32_t, std::uint32_t>> force_bearing_pairs(const ContactList& contacts,
                                                                         const ContactMetricsOptions& options) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (const Contact& contact : contacts) {
    if (!carries_force(contact, options)) continue;
    pairs.emplace_back(std::min(contact.id.body_a, contact.id.body_b), std::max(contact.id.body_a, contact.id.body_b));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

/// phi_i, J/kg: the self-gravity potential of all other grains at each grain (0 for walls), summed
/// exactly (gravity/ direct method: deterministic whatever the thread count).
std::vector<double> self_gravity_potentials(const Model& model, const State& state, const PotentialSettings& settings) {
  std::vector<double> phi(model.body_count(), 0.0);
  std::vector<double> positions, masses;
  std::vector<std::size_t> bodies;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    positions.insert(positions.end(), {state.position[i].x(), state.position[i].y(), state.position[i].z()});
    masses.push_back(model.mass[i]);
    bodies.push_back(i);
  }
  if (masses.size() < 2) return phi;
  gravity::GravityOptions options;
  options.method = gravity::Method::direct;
  options.G = settings.gravitational_constant;
  if (settings.softening > 0.0) options.softening = {gravity::Softening::Kind::plummer, settings.softening};
  std::vector<double> accelerations(positions.size()), potential(masses.size());
  gravity::compute_field(options, positions, masses, accelerations, potential);
  for (std::size_t k = 0; k < bodies.size(); ++k) phi[bodies[k]] = potential[k];
  return phi;
}

/// Farthest point of grain i's surface from `centre`: |x_i - c| + r for a sphere, the farthest
/// vertex for a polyhedron (its convex hull, so a vertex is the farthest point).
double farthest_reach(const Model& model, const State& state, std::size_t i, const Vec3& centre) {
  const Vec3 arm = state.position[i] - centre;
  if (model.shape_kind[i] == ShapeKind::sphere) return arm.norm() + model.sphere_radius(i);
  const ConvexPolyhedron& shape = model.polyhedra[static_cast<std::size_t>(model.shape_index[i])];
  const Mat3 rotation = state.orientation[i].toRotationMatrix();
  double reach = 0.0;
  for (const Vec3& v : shape.vertices) reach = std::max(reach, (arm + rotation * v).squaredNorm());
  return std::sqrt(reach);
}

/// Union-find root with path halving.
std::size_t find_root(std::vector<std::size_t>& parent, std::size_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

GrainSizes grain_sizes(const Model& model) {
  GrainSizes sizes;
  sizes.circumscribed_diameter.assign(model.body_count(), 0.0);
  sizes.equivalent_diameter.assign(model.body_count(), 0.0);
  // One ball per polyhedron shape (bodies may share a shape).
  std::vector<double> polyhedron_diameter(model.polyhedra.size(), 0.0);
  for (std::size_t s = 0; s < model.polyhedra.size(); ++s) {
    polyhedron_diameter[s] = 2.0 * smallest_enclosing_ball(model.polyhedra[s].vertices).radius;
  }
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    sizes.circumscribed_diameter[i] = model.shape_kind[i] == ShapeKind::sphere
                                          ? 2.0 * model.sphere_radius(i)
                                          : polyhedron_diameter[static_cast<std::size_t>(model.shape_index[i])];
    sizes.equivalent_diameter[i] = std::cbrt(6.0 * model.volume[i] / std::numbers::pi);
  }
  return sizes;
}

double kinetic_energy(const Model& model, const State& state) {
  double energy = 0.0;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (model.is_fixed(i)) continue;
    // Rotation in the body frame: w_body = R^T w, E = 1/2 sum_k I_k w_body,k^2.
    const Vec3 w_body = state.orientation[i].conjugate() * state.angular_velocity[i];
    energy += 0.5 * model.mass[i] * state.velocity[i].squaredNorm() +
              0.5 * w_body.dot(model.principal_inertia[i].cwiseProduct(w_body));
  }
  return energy;
}

double potential_energy(const Model& model, const State& state, const PotentialSettings& settings) {
  switch (settings.kind) {
    case PotentialSettings::Kind::none:
      return 0.0;
    case PotentialSettings::Kind::uniform: {
      double energy = 0.0;
      for (std::size_t i = 0; i < model.body_count(); ++i) {
        if (model.is_grain(i)) energy -= model.mass[i] * settings.acceleration.dot(state.position[i]);
      }
      return energy;
    }
    case PotentialSettings::Kind::self: {
      // U = 1/2 sum_i m_i phi_i with phi_i the exact direct-sum potential of the other grains.
      const std::vector<double> phi = self_gravity_potentials(model, state, settings);
      double energy = 0.0;
      for (std::size_t i = 0; i < model.body_count(); ++i) energy += 0.5 * model.mass[i] * phi[i];
      return energy;
    }
  }
  return 0.0;
}

std::vector<int> grain_contact_counts(const Model& model, const ContactList& contacts,
                                      const ContactMetricsOptions& options) {
  std::vector<int> counts(model.body_count(), 0);
  for (const auto& [a, b] : force_bearing_pairs(contacts, options)) {
    if (model.is_grain(a) && model.is_grain(b)) {
      ++counts[a];
      ++counts[b];
    }
  }
  return counts;
}

GrainMomenta grain_momenta(const Model& model, const State& state) {
  GrainMomenta p;
  Vec3 weighted_position = Vec3::Zero();
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    p.linear += model.mass[i] * state.velocity[i];
    p.mass += model.mass[i];
    weighted_position += model.mass[i] * state.position[i];
  }
  p.centre_of_mass = p.mass > 0.0 ? Vec3(weighted_position / p.mass) : Vec3::Zero();
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    const Vec3 arm = state.position[i] - p.centre_of_mass;
    const Mat3 rotation = state.orientation[i].toRotationMatrix();
    const Vec3 spin =
        rotation * model.principal_inertia[i].cwiseProduct(rotation.transpose() * state.angular_velocity[i]);
    p.angular += model.mass[i] * arm.cross(state.velocity[i]) + spin;
  }
  return p;
}

AggregateMetrics compute_metrics(const Model& model, const State& state, const ContactList& contacts,
                                 const PotentialSettings& potential, const ContactMetricsOptions& options) {
  return compute_metrics(model, grain_sizes(model), state, contacts, potential, options);
}

namespace {

/// What later blocks of compute_metrics need from the energies: the grains' total mass and, under
/// self-gravity, each body's potential phi_i (J/kg, 0 for walls; empty otherwise) for the escape test.
struct MassAndPotential {
  double total_mass = 0.0;
  std::vector<double> phi;
};

/// Grains, their volume and kinetic energies (translation and rotation, each summed apart).
void add_grain_energies(const Model& model, const State& state, AggregateMetrics& m) {
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    ++m.grains;
    const Vec3 w_body = state.orientation[i].conjugate() * state.angular_velocity[i];
    m.translational_energy += 0.5 * model.mass[i] * state.velocity[i].squaredNorm();
    m.rotational_energy += 0.5 * w_body.dot(model.principal_inertia[i].cwiseProduct(w_body));
    m.grain_volume += model.volume[i];
  }
}

/// Kinetic, potential and total energy, momenta and centre of mass (docs/postprocessing.md).
MassAndPotential add_energies_and_momenta(const Model& model, const State& state, const PotentialSettings& potential,
                                          AggregateMetrics& m) {
  m.kinetic_energy = m.translational_energy + m.rotational_energy;
  m.mean_kinetic_energy = m.kinetic_energy / static_cast<double>(m.grains);
  // Self-gravity: the per-grain potential serves the energy and the escape test.
  MassAndPotential result;
  if (potential.kind == PotentialSettings::Kind::self) {
    result.phi = self_gravity_potentials(model, state, potential);
    for (std::size_t i = 0; i < model.body_count(); ++i) m.potential_energy += 0.5 * model.mass[i] * result.phi[i];
  } else {
    m.potential_energy = potential_energy(model, state, potential);
  }
  m.total_energy = m.kinetic_energy + m.potential_energy;
  const GrainMomenta momenta = grain_momenta(model, state);
  m.linear_momentum = momenta.linear;
  m.angular_momentum = momenta.angular;
  m.centre_of_mass = momenta.centre_of_mass;
  result.total_mass = momenta.mass;
  return result;
}

/// Sizes, D_max and the packing fraction. Grain diameters are those of the circumscribed spheres
/// (the smallest enclosing balls), as the accretion study measures its grains; D_max reaches the
/// farthest point of any grain from x_cm exactly (a polyhedron's farthest vertex), so it is the
/// diameter of the smallest sphere about x_cm that holds every grain whole.
void add_sizes(const Model& model, const GrainSizes& sizes, const State& state, AggregateMetrics& m) {
  double reach = 0.0, diameter_sum = 0.0, equivalent_sum = 0.0;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    reach = std::max(reach, farthest_reach(model, state, i, m.centre_of_mass));
    diameter_sum += sizes.circumscribed_diameter[i];
    equivalent_sum += sizes.equivalent_diameter[i];
  }
  const auto grains = static_cast<double>(m.grains);
  m.aggregate_diameter = 2.0 * reach;
  m.mean_diameter = diameter_sum / grains;
  m.equivalent_diameter = equivalent_sum / grains;
  const double aggregate_volume = std::numbers::pi * std::pow(m.aggregate_diameter, 3) / 6.0;
  m.packing_fraction = aggregate_volume > 0.0 ? m.grain_volume / aggregate_volume : 0.0;
}

/// Inner sphere: diameter D_max / 2 about the centre of mass, away from the loose surface.
/// Spheres contribute their exact overlap with it; polyhedra their whole volume when their centre
/// is inside (an approximation whose error is confined to the inner sphere's surface). Returns, per
/// body, whether its centre is inside (for the inner coordination).
std::vector<char> add_inner_sphere(const Model& model, const State& state, AggregateMetrics& m) {
  const std::size_t n = model.body_count();
  const double inner_radius = 0.25 * m.aggregate_diameter;
  double inner_volume = 0.0;
  std::vector<char> inner(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!model.is_grain(i)) continue;
    const double d = (state.position[i] - m.centre_of_mass).norm();
    inner[i] = d < inner_radius ? 1 : 0;
    m.inner_grains += inner[i];
    if (model.shape_kind[i] == ShapeKind::sphere) {
      inner_volume += ball_intersection_volume(inner_radius, model.sphere_radius(i), d);
    } else if (inner[i] != 0) {
      inner_volume += model.volume[i];
    }
  }
  const double inner_sphere_volume = 4.0 / 3.0 * std::numbers::pi * std::pow(inner_radius, 3);
  m.inner_packing_fraction = inner_sphere_volume > 0.0 ? inner_volume / inner_sphere_volume : 0.0;
  return inner;
}

/// Inertia-equivalent ellipsoid. D_max and nu above are set by the single farthest grain, so at
/// small n_s the rough surface layer (a grain diameter thick) dominates them: a compact 125-sphere
/// pile whose bulk is at 0.67 gives nu = 0.32. The uniform ellipsoid with the same mass and inertia
/// tensor weighs every grain by its mass, not just the outermost one; its volume is the aggregate's
/// volume as a continuum, and nu_I the aggregate's bulk packing fraction (for one density, the bulk
/// density over the grain density). For a uniform ellipsoid of semi-axes s_i,
/// I_i = M (s_j^2 + s_k^2) / 5, hence s_i^2 = 5 (I_j + I_k - I_i) / (2 M).
void add_inertia_ellipsoid(const Model& model, const State& state, double total_mass, AggregateMetrics& m) {
  Mat3 inertia = Mat3::Zero();
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (!model.is_grain(i)) continue;
    const Vec3 arm = state.position[i] - m.centre_of_mass;
    const Mat3 rotation = state.orientation[i].toRotationMatrix();
    inertia += model.mass[i] * (arm.squaredNorm() * Mat3::Identity() - arm * arm.transpose()) +
               rotation * model.principal_inertia[i].asDiagonal() * rotation.transpose();
  }
  if (!(total_mass > 0.0)) return;
  const Vec3 moments = Eigen::SelfAdjointEigenSolver<Mat3>(inertia, Eigen::EigenvaluesOnly).eigenvalues();  // ascending
  for (int k = 0; k < 3; ++k) {
    // The smallest moment is about the longest axis; max(0, .) guards round-off for a chain.
    m.inertia_semi_axes[k] = std::sqrt(std::max(0.0, 5.0 * (moments.sum() - 2.0 * moments[k]) / (2.0 * total_mass)));
  }
  const double product = m.inertia_semi_axes.prod();
  m.inertia_aspect_ratio = m.inertia_semi_axes[2] > 0.0 ? m.inertia_semi_axes[0] / m.inertia_semi_axes[2] : 0.0;
  m.inertia_diameter = 2.0 * std::cbrt(product);
  m.inertia_packing_fraction = product > 0.0 ? m.grain_volume / (4.0 / 3.0 * std::numbers::pi * product) : 0.0;
}

/// Contact points: count, deepest overlap, force-bearing and sliding points, normal impulses.
void add_contact_points(const ContactList& contacts, const ContactMetricsOptions& options, AggregateMetrics& m) {
  double impulse_sum = 0.0;
  for (const Contact& contact : contacts) {
    ++m.contact_points;
    m.max_overlap = std::max(m.max_overlap, -contact.gap);
    if (!carries_force(contact, options)) continue;
    ++m.force_bearing_points;
    impulse_sum += contact.impulse.x();
    m.max_normal_impulse = std::max(m.max_normal_impulse, contact.impulse.x());
    if (contact.status == ContactStatus::sliding) ++m.sliding_points;
  }
  if (m.force_bearing_points > 0) {
    m.mean_normal_impulse = impulse_sum / static_cast<double>(m.force_bearing_points);
    m.sliding_fraction = static_cast<double>(m.sliding_points) / static_cast<double>(m.force_bearing_points);
  }
}

/// Rattlers, iteratively: a grain with fewer than 2 force-bearing contacts with bodies that are not
/// rattlers (walls never are) is a rattler, and removing it can leave a neighbour with fewer than
/// 2, so the test is repeated until no grain fails it (what is left is the 2-core of the contact
/// network: the backbone). A dangling chain of grains goes whole, not only its last grain.
/// `neighbours[i]` counts the bodies in force-bearing contact with body i, walls included.
std::vector<char> mark_rattlers(const Model& model, const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                                std::vector<int> neighbours) {
  const std::size_t n = model.body_count();
  // The pairs as adjacency lists (compressed rows): body i's neighbours in adjacent[start[i], start[i + 1]).
  std::vector<std::size_t> start(n + 1, 0);
  for (const auto& [a, b] : pairs) {
    ++start[a + 1];
    ++start[b + 1];
  }
  for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
  std::vector<std::uint32_t> adjacent(start[n]);
  std::vector<std::size_t> fill(start.begin(), start.end() - 1);
  for (const auto& [a, b] : pairs) {
    adjacent[fill[a]++] = b;
    adjacent[fill[b]++] = a;
  }
  std::vector<char> rattler(n, 0);
  std::vector<std::size_t> removed;
  for (std::size_t i = 0; i < n; ++i) {
    if (model.is_grain(i) && neighbours[i] < 2) {
      rattler[i] = 1;
      removed.push_back(i);
    }
  }
  while (!removed.empty()) {
    const std::size_t i = removed.back();
    removed.pop_back();
    for (std::size_t k = start[i]; k < start[i + 1]; ++k) {
      const std::uint32_t j = adjacent[k];
      if (rattler[j] != 0 || !model.is_grain(j)) continue;
      if (--neighbours[j] < 2) {
        rattler[j] = 1;
        removed.push_back(j);
      }
    }
  }
  return rattler;
}

/// Pairs in contact, coordination number Z, rattlers, Z without rattlers and the inner sphere's Z.
void add_coordination(const Model& model, const ContactList& contacts, const ContactMetricsOptions& options,
                      const std::vector<char>& inner, AggregateMetrics& m) {
  const std::size_t n = model.body_count();
  const auto pairs = force_bearing_pairs(contacts, options);
  std::vector<int> grain_neighbours(n, 0), all_neighbours(n, 0);
  for (const auto& [a, b] : pairs) {
    const bool grain_a = model.is_grain(a), grain_b = model.is_grain(b);
    if (grain_a && grain_b) {
      ++m.grain_contacts;
      ++grain_neighbours[a];
      ++grain_neighbours[b];
    } else if (grain_a || grain_b) {
      ++m.wall_contacts;
    }
    ++all_neighbours[a];
    ++all_neighbours[b];
  }
  m.coordination = 2.0 * static_cast<double>(m.grain_contacts) / static_cast<double>(m.grains);

  const std::vector<char> rattler = mark_rattlers(model, pairs, all_neighbours);
  std::int64_t inner_contact_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!model.is_grain(i)) continue;
    m.rattlers += rattler[i];
    if (inner[i] != 0) inner_contact_sum += grain_neighbours[i];
  }
  std::int64_t backbone_contacts = 0;
  for (const auto& [a, b] : pairs) {
    if (model.is_grain(a) && model.is_grain(b) && rattler[a] == 0 && rattler[b] == 0) ++backbone_contacts;
  }
  const std::int64_t backbone_grains = m.grains - m.rattlers;
  m.coordination_without_rattlers =
      backbone_grains > 0 ? 2.0 * static_cast<double>(backbone_contacts) / static_cast<double>(backbone_grains) : 0.0;
  m.inner_coordination =
      m.inner_grains > 0 ? static_cast<double>(inner_contact_sum) / static_cast<double>(m.inner_grains) : 0.0;
}

/// Detached grains: outside the largest cluster of the contact network. Every listed point joins
/// its pair, force-bearing or not: in a frictionless pile at rest the forces are not unique
/// (Radjai & Dubois 2011), so a touching grain may carry none at one instant yet is no less part of
/// the aggregate. Escaping ones among them need the self-gravity potential (`gravity.phi`).
void add_detached_grains(const Model& model, const State& state, const ContactList& contacts,
                         const MassAndPotential& gravity, AggregateMetrics& m) {
  const std::size_t n = model.body_count();
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  for (const Contact& contact : contacts) {
    if (!model.is_grain(contact.id.body_a) || !model.is_grain(contact.id.body_b)) continue;
    const std::size_t a = find_root(parent, contact.id.body_a), b = find_root(parent, contact.id.body_b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
  std::vector<std::int64_t> cluster_size(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (model.is_grain(i)) ++cluster_size[find_root(parent, i)];
  }
  const std::size_t largest =
      static_cast<std::size_t>(std::max_element(cluster_size.begin(), cluster_size.end()) - cluster_size.begin());
  const double total_mass = gravity.total_mass;
  const Vec3 v_cm = total_mass > 0.0 ? Vec3(m.linear_momentum / total_mass) : Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!model.is_grain(i) || find_root(parent, i) == largest) continue;
    ++m.detached_grains;
    // Escape: positive specific energy in the field of all the other grains, the velocity taken
    // relative to the grains' centre of mass (the aggregate's frame).
    const std::vector<double>& phi = gravity.phi;
    if (!phi.empty() && 0.5 * (state.velocity[i] - v_cm).squaredNorm() + phi[i] > 0.0) ++m.escaping_grains;
  }
}

}  // namespace

AggregateMetrics compute_metrics(const Model& model, const GrainSizes& sizes, const State& state,
                                 const ContactList& contacts, const PotentialSettings& potential,
                                 const ContactMetricsOptions& options) {
  AggregateMetrics m;
  m.time = state.time;
  m.step = state.step;
  add_grain_energies(model, state, m);
  if (m.grains == 0) return m;
  const MassAndPotential gravity = add_energies_and_momenta(model, state, potential, m);
  add_sizes(model, sizes, state, m);
  const std::vector<char> inner = add_inner_sphere(model, state, m);
  add_inertia_ellipsoid(model, state, gravity.total_mass, m);
  add_contact_points(contacts, options, m);
  add_coordination(model, contacts, options, inner, m);
  add_detached_grains(model, state, contacts, gravity, m);
  return m;
}

ImpulseHistogram normal_impulse_histogram(const ContactList& contacts, int bins, const ContactMetricsOptions& options) {
  ImpulseHistogram histogram;
  std::vector<double> impulses;
  for (const Contact& contact : contacts) {
    if (carries_force(contact, options)) impulses.push_back(contact.impulse.x());
  }
  if (impulses.empty() || bins < 1) return histogram;
  double sum = 0.0;
  for (double r : impulses) sum += r;
  const double mean = sum / static_cast<double>(impulses.size());
  histogram.mean_normal_impulse = mean;
  const double upper = std::max(1.0, std::ceil(*std::max_element(impulses.begin(), impulses.end()) / mean));
  const double width = upper / bins;
  histogram.count.assign(static_cast<std::size_t>(bins), 0);
  for (double r : impulses) {
    const auto bin = std::min(static_cast<std::size_t>(r / mean / width), static_cast<std::size_t>(bins - 1));
    ++histogram.count[bin];
  }
  for (int k = 0; k < bins; ++k) {
    histogram.bin_lower.push_back(k * width);
    histogram.bin_upper.push_back((k + 1) * width);
    histogram.density.push_back(static_cast<double>(histogram.count[static_cast<std::size_t>(k)]) /
                                (static_cast<double>(impulses.size()) * width));
  }
  return histogram;
}

}  // namespace rubble
