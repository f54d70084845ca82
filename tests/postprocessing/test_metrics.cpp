// Metrics of an aggregate on hand-built configurations whose answers are known in closed form:
// simple cubic and FCC lattices, a chain, a lone grain, two orbiting grains.
#include "postprocessing/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/polyhedron.hpp"
#include "test_shapes.hpp"

namespace rubble {
namespace {

constexpr double pi = std::numbers::pi;

/// A model of spheres of one radius at the given centres (material density 1000).
struct Packing {
  Model model;
  State state;
};

Packing spheres_at(const std::vector<Vec3>& centres, double radius) {
  Packing p;
  p.model.materials = {{"rock", 1000.0}};
  p.model.contact_laws.reset(1, ContactLaw{});
  for (std::size_t i = 0; i < centres.size(); ++i) add_sphere(p.model, radius, 0);
  p.state.resize(centres.size());
  p.state.position = centres;
  return p;
}

/// One force-bearing contact point (impulse r_n along the normal from a to b) per pair of
/// grains whose centres are `spacing` apart, found by brute force.
ContactList touching_pairs(const std::vector<Vec3>& centres, double spacing, double impulse = 1.0) {
  ContactList contacts;
  for (std::size_t a = 0; a < centres.size(); ++a) {
    for (std::size_t b = a + 1; b < centres.size(); ++b) {
      const Vec3 d = centres[b] - centres[a];
      if (std::abs(d.norm() - spacing) > 1e-9 * spacing) continue;
      Contact c;
      c.id.body_a = static_cast<std::uint32_t>(a);
      c.id.body_b = static_cast<std::uint32_t>(b);
      c.point = centres[a] + 0.5 * d;
      c.frame = frame_from_normal(d.normalized());
      c.impulse = Vec3(impulse, 0.0, 0.0);
      c.status = ContactStatus::sticking;
      contacts.push_back(c);
    }
  }
  return contacts;
}

TEST(Metrics, SimpleCubicLattice) {
  // n^3 touching spheres on a cubic grid of spacing d: 3 n^2 (n - 1) contacts, so
  // Z = 6 (n - 1) / n; every bulk grain has 6; corners have 3, so there is no rattler.
  // The inner sphere (radius D_max / 4 = 4.15 d) samples the lattice's packing fraction pi/6;
  // cutting the lattice by a sphere of that size moves it by < 1% (0.3% in an independent numpy evaluation).
  const int n = 10;
  const double d = 1.0;
  std::vector<Vec3> centres;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) centres.emplace_back(i * d, j * d, k * d);
  const Packing p = spheres_at(centres, 0.5 * d);
  const ContactList contacts = touching_pairs(centres, d);
  ASSERT_EQ(contacts.size(), static_cast<std::size_t>(3 * n * n * (n - 1)));
  const AggregateMetrics m = compute_metrics(p.model, p.state, contacts);
  EXPECT_EQ(m.grains, n * n * n);
  EXPECT_DOUBLE_EQ(m.coordination, 6.0 * (n - 1) / n);
  EXPECT_EQ(m.rattlers, 0);
  EXPECT_DOUBLE_EQ(m.coordination_without_rattlers, m.coordination);
  EXPECT_DOUBLE_EQ(m.inner_coordination, 6.0);
  // D_max: the corner grains, sqrt(3) (n-1)/2 d from the centre, plus a radius.
  EXPECT_NEAR(m.aggregate_diameter, 2.0 * (std::sqrt(3.0) * (n - 1) / 2.0 * d + 0.5 * d), 1e-12);
  EXPECT_NEAR(m.centre_of_mass.norm(), std::sqrt(3.0) * (n - 1) / 2.0 * d, 1e-12);
  const double grain_volume = n * n * n * pi * d * d * d / 6.0;
  EXPECT_NEAR(m.packing_fraction, grain_volume / (pi * std::pow(m.aggregate_diameter, 3) / 6.0), 1e-12);
  EXPECT_NEAR(m.inner_packing_fraction, pi / 6.0, 0.01 * pi / 6.0);
  EXPECT_DOUBLE_EQ(m.mean_diameter, d);
  EXPECT_NEAR(m.equivalent_diameter, d, 1e-12);
}

TEST(Metrics, FaceCentredCubicLattice) {
  // FCC with cube side a: spheres of radius a / (2 sqrt 2) touch their 12 neighbours at a / sqrt 2.
  // Every inner grain has Z = 12, and the inner packing fraction is the lattice's pi / (3 sqrt 2)
  // (0.7405) within 1%: the inner sphere's radius is 3.4 a, and its cut through the lattice moves
  // the value by 0.03% (an independent numpy evaluation of the same cut).
  const int k = 8;
  const double a = 1.0;
  const double spacing = a / std::sqrt(2.0);
  std::vector<Vec3> centres;
  const Vec3 basis[4] = {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5), Vec3(0, 0.5, 0.5)};
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      for (int l = 0; l < k; ++l)
        for (const Vec3& b : basis) centres.push_back(a * (Vec3(i, j, l) + b));
  const Packing p = spheres_at(centres, 0.5 * spacing);
  const AggregateMetrics m = compute_metrics(p.model, p.state, touching_pairs(centres, spacing));
  EXPECT_GT(m.inner_grains, 100);
  EXPECT_DOUBLE_EQ(m.inner_coordination, 12.0);
  EXPECT_LT(m.coordination, 12.0);  // the surface grains have fewer
  EXPECT_NEAR(m.inner_packing_fraction, pi / (3.0 * std::sqrt(2.0)), 0.01 * pi / (3.0 * std::sqrt(2.0)));
}

TEST(Metrics, ChainOfGrains) {
  // N touching spheres in a line: N - 1 contacts, Z = 2 - 2 / N. The two ends have one contact:
  // rattlers; once they are gone the next two have one, and so on: the whole chain is rattlers
  // (no backbone, Z' = 0). D_max = N d and nu = 1 / N^2.
  const int n = 7;
  const double d = 2.0;
  std::vector<Vec3> centres;
  for (int i = 0; i < n; ++i) centres.emplace_back(i * d, 0.0, 0.0);
  const Packing p = spheres_at(centres, 0.5 * d);
  const AggregateMetrics m = compute_metrics(p.model, p.state, touching_pairs(centres, d));
  EXPECT_DOUBLE_EQ(m.coordination, 2.0 - 2.0 / n);
  EXPECT_EQ(m.rattlers, n);
  EXPECT_DOUBLE_EQ(m.coordination_without_rattlers, 0.0);
  EXPECT_NEAR(m.aggregate_diameter, n * d, 1e-12);
  EXPECT_NEAR(m.packing_fraction, 1.0 / (n * n), 1e-12);
  EXPECT_EQ(m.grain_contacts, n - 1);
  EXPECT_EQ(m.wall_contacts, 0);
}

TEST(Metrics, WallContactsAreNotGrainContactsButHoldRattlers) {
  // A row of N touching spheres lying on a plane wall, each pressed on it: Z is that of the chain
  // (the wall is no grain), the wall contacts are counted apart, and every grain, with the wall
  // and at least one neighbour, has 2 force-bearing contacts: no rattler (the chain alone, above,
  // is all rattlers). A grain set on top of the second one, touching it only, is one, and takes
  // no other grain with it: the one below keeps the wall and its row neighbours.
  const int n = 5;
  const double d = 1.0;
  std::vector<Vec3> centres;
  for (int i = 0; i < n; ++i) centres.emplace_back(i * d, 0.0, 0.5 * d);
  centres.emplace_back(d, 0.0, 1.5 * d);
  Packing p = spheres_at(centres, 0.5 * d);
  ContactList contacts = touching_pairs(centres, d);
  const int wall = add_plane_wall(p.model, Vec3::UnitZ(), 0);
  p.state.position.push_back(Vec3::Zero());
  p.state.orientation.push_back(Quat::Identity());
  p.state.velocity.push_back(Vec3::Zero());
  p.state.angular_velocity.push_back(Vec3::Zero());
  for (int i = 0; i < n; ++i) {
    Contact floor;
    floor.id.body_a = static_cast<std::uint32_t>(wall);
    floor.id.body_b = static_cast<std::uint32_t>(i);
    floor.frame = frame_from_normal(Vec3::UnitZ());
    floor.impulse = Vec3(3.0, 0.0, 0.0);
    contacts.push_back(floor);
  }
  const AggregateMetrics m = compute_metrics(p.model, p.state, contacts);
  EXPECT_EQ(m.grains, n + 1);
  EXPECT_EQ(m.grain_contacts, n);  // the row's n - 1 and the top grain's one
  EXPECT_DOUBLE_EQ(m.coordination, 2.0 * n / (n + 1));
  EXPECT_EQ(m.wall_contacts, n);
  EXPECT_EQ(m.rattlers, 1);  // only the top grain
  EXPECT_DOUBLE_EQ(m.coordination_without_rattlers, 2.0 * (n - 1) / n);
  // The infinite wall is no part of D_max: the centre of mass is (11/6, 0, 2/3) d, the farthest
  // grain the row's last, (4, 0, 1/2) d, at sqrt(13^2 + 1) / 6 d.
  EXPECT_NEAR(m.aggregate_diameter, std::sqrt(170.0) / 3.0 * d + d, 1e-12);
}

TEST(Metrics, RattlersAreRemovedUntilNoneIsLeft) {
  // A tetrahedron of 4 mutually touching spheres (6 contacts, 3 a grain) with a chain of 2 more
  // sticking out of its first vertex, away from the others. One pass would find only the chain's
  // tip (1 contact) and keep the middle grain (2); once the tip is gone the middle grain has 1
  // and goes too. What is left is the tetrahedron: Z' = 2 * 6 / 4 = 3, with Z = 2 * 8 / 6.
  const double d = 1.0;
  std::vector<Vec3> centres = {Vec3(1, 1, 1), Vec3(1, -1, -1), Vec3(-1, 1, -1), Vec3(-1, -1, 1)};
  for (Vec3& c : centres) c *= d / std::sqrt(8.0);  // edge |(0, 2, 2)| / sqrt(8) = d
  const Vec3 out = centres[0].normalized();         // from the tetrahedron's centre (the origin)
  centres.push_back(centres[0] + d * out);
  centres.push_back(centres[0] + 2.0 * d * out);
  const Packing p = spheres_at(centres, 0.5 * d);
  const AggregateMetrics m = compute_metrics(p.model, p.state, touching_pairs(centres, d));
  EXPECT_EQ(m.grain_contacts, 8);
  EXPECT_DOUBLE_EQ(m.coordination, 2.0 * 8 / 6);
  EXPECT_EQ(m.rattlers, 2);
  EXPECT_DOUBLE_EQ(m.coordination_without_rattlers, 3.0);
}

TEST(Metrics, SeveralPointsOfOnePairAreOneContactAndZeroImpulsesDoNotCount) {
  // Two boxes face to face touch at 4 points: one grain contact (Z = 1). A third grain whose
  // contact has no normal impulse is not connected. Two of the 4 points slide.
  Model model;
  model.materials = {{"rock", 1000.0}};
  model.contact_laws.reset(1, ContactLaw{});
  const Vec3 half(0.5, 0.5, 0.5);
  for (int i = 0; i < 2; ++i)
    add_polyhedron(model, test::box_polyhedron(half), 1.0, test::box_inertia_per_density(half), 0);
  add_sphere(model, 0.5, 0);
  State state;
  state.resize(3);
  state.position = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)};
  ContactList contacts(5);
  for (int k = 0; k < 4; ++k) {
    contacts[k].id = {0, 1, static_cast<std::uint32_t>(k), 0};
    contacts[k].impulse = Vec3(1.0 + k, 0.0, 0.0);
    contacts[k].status = k < 2 ? ContactStatus::sliding : ContactStatus::sticking;
  }
  contacts[4].id = {1, 2, 0, 0};
  contacts[4].impulse = Vec3::Zero();
  const AggregateMetrics m = compute_metrics(model, state, contacts);
  EXPECT_EQ(m.contact_points, 5);
  EXPECT_EQ(m.force_bearing_points, 4);
  EXPECT_EQ(m.grain_contacts, 1);
  EXPECT_DOUBLE_EQ(m.coordination, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(m.sliding_fraction, 0.5);
  EXPECT_DOUBLE_EQ(m.mean_normal_impulse, 2.5);
  EXPECT_DOUBLE_EQ(m.max_normal_impulse, 4.0);
  EXPECT_EQ(m.rattlers, 3);  // each grain has a single force-bearing neighbour at most
  const std::vector<int> counts = grain_contact_counts(model, contacts);
  EXPECT_EQ(counts, (std::vector<int>{1, 1, 0}));
  // d*: a unit cube has the volume of a ball of diameter (6/pi)^(1/3); the sphere's is 1.
  EXPECT_NEAR(m.equivalent_diameter, (2.0 * std::cbrt(6.0 / pi) + 1.0) / 3.0, 1e-12);
  EXPECT_NEAR(m.mean_diameter, (2.0 * std::sqrt(3.0) + 1.0) / 3.0, 1e-12);
}

TEST(Metrics, LoneGrain) {
  // A single sphere: no contact, a rattler, D_max = its diameter, nu = 1, and the inner sphere
  // (half its diameter) is full.
  const Packing p = spheres_at({Vec3(3.0, -1.0, 2.0)}, 0.75);
  const AggregateMetrics m = compute_metrics(p.model, p.state, {});
  EXPECT_EQ(m.grains, 1);
  EXPECT_DOUBLE_EQ(m.coordination, 0.0);
  EXPECT_EQ(m.rattlers, 1);
  EXPECT_DOUBLE_EQ(m.coordination_without_rattlers, 0.0);
  EXPECT_NEAR(m.aggregate_diameter, 1.5, 1e-15);
  EXPECT_NEAR(m.packing_fraction, 1.0, 1e-12);
  EXPECT_NEAR(m.inner_packing_fraction, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(m.sliding_fraction, 0.0);
}

/// A square pyramid: base corners (+-b, +-b, 0) with b = 1/sqrt(2) (1 from the axis), apex
/// (0, 0, 3), built by make_convex_polyhedron (origin moved to the centroid, z = 3/4).
ConvexPolyhedron square_pyramid() {
  const double b = 1.0 / std::sqrt(2.0);
  return make_convex_polyhedron({Vec3(b, b, 0), Vec3(-b, b, 0), Vec3(-b, -b, 0), Vec3(b, -b, 0), Vec3(0, 0, 3)},
                                {{3, 2, 1, 0}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}});
}

TEST(GrainSizes, CircumscribedSphereOfAPyramidIsNotTheBallAboutItsCentroid) {
  // The smallest ball enclosing the pyramid passes through the apex and the 4 base corners; by
  // symmetry its centre is on the axis at height c with c^2 + 1 = (3 - c)^2: c = 4/3, radius
  // 5/3, diameter 10/3. The ball about the centroid (z = 3/4, the mean of a cone's height) must
  // reach the apex: radius 9/4, diameter 4.5, 35% larger. <d> is the former (the accretion
  // study's circumscribed sphere), as docs/postprocessing.md says.
  Model model;
  model.materials = {{"rock", 1000.0}};
  model.contact_laws.reset(1, ContactLaw{});
  add_polyhedron_grain(model, square_pyramid(), 0);
  add_sphere(model, 0.75, 0);
  ASSERT_NEAR(model.bounding_radius[0], 2.25, 1e-12);  // the old <d> was twice this
  const GrainSizes sizes = grain_sizes(model);
  EXPECT_NEAR(sizes.circumscribed_diameter[0], 10.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(sizes.circumscribed_diameter[1], 1.5);                       // a sphere: its diameter
  EXPECT_NEAR(sizes.equivalent_diameter[0], std::cbrt(6.0 * 2.0 / pi), 1e-12);  // V = (1/3) 2 * 3 = 2
  State state;
  state.resize(2);
  state.position = {Vec3(0, 0, 0), Vec3(100, 0, 0)};
  const AggregateMetrics m = compute_metrics(model, sizes, state, {});
  EXPECT_NEAR(m.mean_diameter, (10.0 / 3.0 + 1.5) / 2.0, 1e-12);
  EXPECT_NEAR(m.equivalent_diameter, (std::cbrt(12.0 / pi) + 1.5) / 2.0, 1e-12);
  // The overload without sizes computes the same.
  EXPECT_DOUBLE_EQ(compute_metrics(model, state, {}).mean_diameter, m.mean_diameter);
}

TEST(Metrics, AggregateDiameterReachesThePolyhedraFarthestVertices) {
  // Two pyramids on the x axis at -+L, apexes pointing at each other (body z to world +x for the
  // left one, -x for the right one), x_cm = 0. The farthest points from x_cm are the base
  // corners, 3/4 behind each centroid and 1 off the axis: D_max = 2 sqrt((L + 3/4)^2 + 1). The
  // bound |x_i - x_cm| + bounding radius would give 2 (L + 9/4), 24% more for L = 5.
  Model model;
  model.materials = {{"rock", 1000.0}};
  model.contact_laws.reset(1, ContactLaw{});
  for (int i = 0; i < 2; ++i) add_polyhedron_grain(model, square_pyramid(), 0);
  const double L = 5.0;
  State state;
  state.resize(2);
  state.position = {Vec3(-L, 0, 0), Vec3(L, 0, 0)};
  state.orientation = {Quat(Eigen::AngleAxisd(pi / 2, Vec3::UnitY())), Quat(Eigen::AngleAxisd(-pi / 2, Vec3::UnitY()))};
  const AggregateMetrics m = compute_metrics(model, state, {});
  EXPECT_NEAR(m.aggregate_diameter, 2.0 * std::sqrt((L + 0.75) * (L + 0.75) + 1.0), 1e-12);
  EXPECT_NEAR(m.packing_fraction, 4.0 / (pi * std::pow(m.aggregate_diameter, 3) / 6.0), 1e-12);
}

TEST(Metrics, DeepestOverlapDetachedAndEscapingGrains) {
  // Grains 0 and 1 touch (one listed point, gap -0.01 m). Grain 2 is 1000 m away at rest: detached
  // but bound. Grain 3 is 1000 m away the other side at 1 mm/s: detached, and its energy in the
  // field of the others, 1/2 |v - v_cm|^2 - G sum_j m_j / r_j, is positive (escape speed
  // sqrt(2 G 3 m / 1000 m) ~ 1e-5 m/s for these 4.2 t grains). A listed point joins its pair
  // even without impulse (grain 1 - grain 4): grain 4 is in the aggregate.
  const std::vector<Vec3> centres{Vec3(0, 0, 0), Vec3(1.99, 0, 0), Vec3(1000, 0, 0), Vec3(-1000, 0, 0),
                                  Vec3(3.98, 0, 0)};
  Packing p = spheres_at(centres, 1.0);
  p.state.velocity[3] = Vec3(-1e-3, 0, 0);
  p.state.velocity[0] = Vec3(1e-3, 0, 0);  // v_cm = 0: grain 2 is at rest in the aggregate's frame
  ContactList contacts(2);
  contacts[0].id = {0, 1, 0, 0};
  contacts[0].gap = -0.01;
  contacts[0].impulse = Vec3(1.0, 0, 0);
  contacts[1].id = {1, 4, 0, 0};
  contacts[1].gap = -0.01 + 1e-9;
  PotentialSettings gravity;
  gravity.kind = PotentialSettings::Kind::self;
  const AggregateMetrics m = compute_metrics(p.model, p.state, contacts, gravity);
  EXPECT_NEAR(m.max_overlap, 0.01, 1e-15);
  EXPECT_EQ(m.detached_grains, 2);
  EXPECT_EQ(m.escaping_grains, 1);
  // Grain 3's energy by hand, to show the margin is not round-off.
  const double mass = p.model.mass[0], G = gravity.gravitational_constant;
  double phi = 0.0;
  for (int j : {0, 1, 2, 4}) phi -= G * mass / (centres[3] - centres[static_cast<std::size_t>(j)]).norm();
  EXPECT_GT(0.5 * p.state.velocity[3].squaredNorm() + phi, 1e-7);
  for (int j : {0, 1, 3, 4}) phi -= G * mass / (centres[2] - centres[static_cast<std::size_t>(j)]).norm();
  EXPECT_LT(phi, 0.0);  // grain 2, at rest
  // Without self-gravity no grain is counted as escaping.
  EXPECT_EQ(compute_metrics(p.model, p.state, contacts).escaping_grains, 0);
}

TEST(Metrics, NoGrainAtAll) {
  Model model;
  model.materials = {{"rock", 1000.0}};
  add_plane_wall(model, Vec3::UnitZ(), 0);
  State state;
  state.resize(1);
  const AggregateMetrics m = compute_metrics(model, state, {});
  EXPECT_EQ(m.grains, 0);
  EXPECT_DOUBLE_EQ(m.packing_fraction, 0.0);
}

TEST(Metrics, EnergiesAndMomentaOfTwoOrbitingGrains) {
  // Two equal spheres at +-x0 moving at -+v along y, spinning at w about z. The centre of mass
  // is the origin, P = 0, L = 2 m x0 v + 2 (2/5 m r^2) w along z (the orbit's sign: x0 e_x x
  // (-v e_y) = -x0 v e_z, so L_z = -2 m x0 v + 2 I w). Self-gravity: U = -G m^2 / (2 x0).
  const double r = 0.5, x0 = 2.0, v = 0.3, w = 0.7;
  Packing p = spheres_at({Vec3(x0, 0, 0), Vec3(-x0, 0, 0)}, r);
  p.state.velocity = {Vec3(0, -v, 0), Vec3(0, v, 0)};
  p.state.angular_velocity = {Vec3(0, 0, w), Vec3(0, 0, w)};
  const double mass = p.model.mass[0];
  const double inertia = 0.4 * mass * r * r;
  PotentialSettings self;
  self.kind = PotentialSettings::Kind::self;
  self.gravitational_constant = 6.674e-11;
  const AggregateMetrics m = compute_metrics(p.model, p.state, {}, self);
  EXPECT_NEAR(m.linear_momentum.norm(), 0.0, 1e-15);
  EXPECT_NEAR(m.angular_momentum.z(), -2.0 * mass * x0 * v + 2.0 * inertia * w, 1e-12);
  EXPECT_NEAR(m.angular_momentum.head<2>().norm(), 0.0, 1e-15);
  const double kinetic = mass * v * v + inertia * w * w;
  EXPECT_NEAR(m.kinetic_energy, kinetic, 1e-12 * kinetic);
  EXPECT_NEAR(m.mean_kinetic_energy, kinetic / 2.0, 1e-12 * kinetic);
  EXPECT_NEAR(m.rotational_energy, inertia * w * w, 1e-12 * kinetic);
  const double potential = -6.674e-11 * mass * mass / (2.0 * x0);
  EXPECT_NEAR(m.potential_energy, potential, 1e-12 * std::abs(potential));
  EXPECT_NEAR(m.total_energy, kinetic + potential, 1e-12 * kinetic);

  PotentialSettings uniform;
  uniform.kind = PotentialSettings::Kind::uniform;
  uniform.acceleration = Vec3(0, 0, -9.81);
  p.state.position[1].z() = 3.0;  // U = m g z for the raised grain only
  EXPECT_NEAR(potential_energy(p.model, p.state, uniform), mass * 9.81 * 3.0, 1e-12 * mass * 30.0);
}

TEST(Metrics, NormalImpulseHistogram) {
  // Impulses 1, 1, 2, 4 (mean 2): normalised 0.5, 0.5, 1, 2 over [0, 2] in 4 bins of 0.5.
  ContactList contacts(5);
  const double impulses[5] = {1.0, 1.0, 2.0, 4.0, 0.0};
  for (int k = 0; k < 5; ++k) contacts[k].impulse = Vec3(impulses[k], 0.0, 0.0);
  const ImpulseHistogram h = normal_impulse_histogram(contacts, 4);
  EXPECT_DOUBLE_EQ(h.mean_normal_impulse, 2.0);
  ASSERT_EQ(h.count.size(), 4u);
  EXPECT_EQ(h.count, (std::vector<std::int64_t>{0, 2, 1, 1}));
  EXPECT_DOUBLE_EQ(h.bin_upper.back(), 2.0);
  double integral = 0.0;
  for (std::size_t k = 0; k < 4; ++k) integral += h.density[k] * (h.bin_upper[k] - h.bin_lower[k]);
  EXPECT_NEAR(integral, 1.0, 1e-15);
  EXPECT_TRUE(normal_impulse_histogram(ContactList{}, 4).count.empty());
}

TEST(Metrics, RowMatchesColumnNames) {
  EXPECT_EQ(metrics_row(AggregateMetrics{}).size(), metrics_column_names().size());
}

TEST(KineticEnergy, SphereTranslationPlusRotation) {
  Model model;
  model.materials = {{"rock", 2000.0}};
  add_sphere(model, 0.5, 0);
  State state;
  state.resize(1);
  state.velocity[0] = Vec3(1.0, -2.0, 2.0);         // |v|^2 = 9
  state.angular_velocity[0] = Vec3(0.0, 3.0, 4.0);  // |w|^2 = 25
  const double m = 2000.0 * 4.0 / 3.0 * pi * 0.125;
  const double expected = 0.5 * m * 9.0 + 0.5 * (0.4 * m * 0.25) * 25.0;
  EXPECT_NEAR(kinetic_energy(model, state), expected, 1e-12 * expected);
}

TEST(KineticEnergy, RotatedBoxUsesTheWorldInertiaTensor) {
  // E_rot = 1/2 w^T R diag(I) R^T w, with the tensor built explicitly here.
  Model model;
  model.materials = {{"rock", 1500.0}};
  const Vec3 half(1.0, 0.5, 0.25);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half), 0);
  add_plane_wall(model, Vec3::UnitZ(), 0);
  State state;
  state.resize(2);
  state.orientation[0] = Quat(Eigen::AngleAxisd(0.7, Vec3(1.0, -1.0, 2.0).normalized()));
  state.velocity[0] = Vec3(0.3, 0.0, 0.0);
  state.angular_velocity[0] = Vec3(0.2, -1.0, 0.5);
  state.velocity[1] = Vec3(5.0, 5.0, 5.0);  // a wall never contributes, whatever its velocity says
  const Mat3 rotation = state.orientation[0].toRotationMatrix();
  const Mat3 world_inertia = rotation * model.principal_inertia[0].asDiagonal() * rotation.transpose();
  const Vec3 w = state.angular_velocity[0];
  const double expected = 0.5 * model.mass[0] * 0.09 + 0.5 * w.dot(world_inertia * w);
  EXPECT_NEAR(kinetic_energy(model, state), expected, 1e-12 * expected);
}

// Inertia-equivalent ellipsoid (s_i^2 = 5 (I_j + I_k - I_i) / (2 M)), nu_I and D_I.
TEST(InertiaEllipsoid, LoneSphereIsItself) {
  // A uniform ball is its own inertia-equivalent ellipsoid: s_i = r, D_I = 2 r, nu_I = 1.
  const Packing p = spheres_at({Vec3(3.0, -1.0, 5.0)}, 2.0);
  const AggregateMetrics m = compute_metrics(p.model, p.state, {});
  EXPECT_NEAR((m.inertia_semi_axes - Vec3(2.0, 2.0, 2.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(m.inertia_diameter, 4.0, 1e-12);
  EXPECT_NEAR(m.inertia_packing_fraction, 1.0, 1e-12);
  EXPECT_NEAR(m.inertia_aspect_ratio, 1.0, 1e-12);
}

TEST(InertiaEllipsoid, ChainOfGrains) {
  // N spheres (radius r, mass m) spaced d on the x axis: I_xx = N (2/5) m r^2 and
  // I_yy = I_zz = N (2/5) m r^2 + m d^2 N (N^2 - 1) / 12, so s_1^2 = r^2 + 5 d^2 (N^2 - 1) / 12,
  // s_2 = s_3 = r, nu_I = N r / s_1.
  const int n = 7;
  const double d = 2.0, r = 1.0;
  std::vector<Vec3> centres;
  for (int i = 0; i < n; ++i) centres.emplace_back(i * d, 0.0, 0.0);
  const Packing p = spheres_at(centres, r);
  const AggregateMetrics m = compute_metrics(p.model, p.state, {});
  const double s1 = std::sqrt(r * r + 5.0 * d * d * (n * n - 1) / 12.0);
  EXPECT_NEAR(m.inertia_semi_axes.x(), s1, 1e-12 * s1);
  EXPECT_NEAR(m.inertia_semi_axes.y(), r, 1e-12);
  EXPECT_NEAR(m.inertia_semi_axes.z(), r, 1e-12);
  EXPECT_NEAR(m.inertia_aspect_ratio, s1 / r, 1e-12 * s1);
  EXPECT_NEAR(m.inertia_packing_fraction, n * r / s1, 1e-12);
  EXPECT_NEAR(m.inertia_diameter, 2.0 * std::cbrt(s1 * r * r), 1e-12);
}

TEST(InertiaEllipsoid, RotatedBoxUsesItsOwnWorldInertia) {
  // A lone uniform box of half-extents h: I_x = M (h_y^2 + h_z^2) / 3, so s_i = sqrt(5/3) h_i
  // whatever its orientation, and nu_I = 8 h_x h_y h_z / (4/3 pi (5/3)^(3/2) h_x h_y h_z) = 6 / (pi (5/3)^(3/2)).
  Model model;
  model.materials = {{"rock", 1500.0}};
  const Vec3 half(1.0, 0.5, 0.25);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half), 0);
  State state;
  state.resize(1);
  state.position[0] = Vec3(10.0, 0.0, -4.0);
  state.orientation[0] = Quat(Eigen::AngleAxisd(0.7, Vec3(1.0, -1.0, 2.0).normalized()));
  const AggregateMetrics m = compute_metrics(model, state, {});
  EXPECT_NEAR((m.inertia_semi_axes - std::sqrt(5.0 / 3.0) * half).norm(), 0.0, 1e-12);
  EXPECT_NEAR(m.inertia_packing_fraction, 6.0 / (pi * std::pow(5.0 / 3.0, 1.5)), 1e-12);
  EXPECT_NEAR(m.inertia_aspect_ratio, 4.0, 1e-12);
}

TEST(InertiaEllipsoid, BallOfFaceCentredCubicLatticeHasTheLatticePackingFraction) {
  // The FCC sites within 6 a of a site, spheres of radius a / (2 sqrt 2): a ball of the lattice,
  // so nu_I is the lattice's pi / (3 sqrt 2) = 0.7405 up to the cut's discreteness; an independent
  // numpy evaluation of the same ball gives 0.7366 (3 589 grains), hence the 1% tolerance.
  const double a = 1.0;
  const Vec3 centre(8.0, 8.0, 8.0);
  const Vec3 basis[4] = {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5), Vec3(0, 0.5, 0.5)};
  std::vector<Vec3> centres;
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j)
      for (int l = 0; l < 16; ++l)
        for (const Vec3& b : basis) {
          const Vec3 x = a * (Vec3(i, j, l) + b);
          if ((x - centre).norm() <= 6.0 * a) centres.push_back(x);
        }
  ASSERT_EQ(centres.size(), 3589u);
  const Packing p = spheres_at(centres, a / (2.0 * std::sqrt(2.0)));
  const AggregateMetrics m = compute_metrics(p.model, p.state, {});
  const double lattice = pi / (3.0 * std::sqrt(2.0));
  EXPECT_NEAR(m.inertia_packing_fraction, lattice, 0.01 * lattice);
  EXPECT_NEAR(m.inertia_aspect_ratio, 1.0, 1e-9);  // cubic symmetry: an isotropic tensor
  // The encompassing sphere of the same ball is looser: its surface layer is counted as void.
  EXPECT_LT(m.packing_fraction, m.inertia_packing_fraction);
}

}  // namespace
}  // namespace rubble
