#pragma once
// Metrics of a granular aggregate at one instant (the LMGC90 accretion paper section 3): energies and momenta,
// coordination number with and without rattlers, aggregate diameter, packing fraction, contact
// statistics. The exact definitions are in docs/postprocessing.md; every function takes the
// immutable Model and one State (plus the contacts where needed), so it runs during a run or on a
// run file afterwards. Walls are bodies but never grains: they are left out of every sum over
// grains; a grain's contact with a wall counts as force-bearing for the rattler test only.
#include <cstdint>
#include <string>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Total kinetic energy of the moving bodies, J: sum over bodies of
/// 1/2 m |v|^2 + 1/2 w . (R I R^T) w (translation + rotation; w and v in the world frame,
/// I the principal inertia in the body frame, R the body's rotation). Walls contribute nothing.
double kinetic_energy(const Model& model, const State& state);

/// Linear momentum of the grains and their angular momentum about their centre of mass.
struct GrainMomenta {
  Vec3 linear = Vec3::Zero();          ///< kg m/s, sum m v
  Vec3 angular = Vec3::Zero();         ///< kg m^2/s, sum m (x - x_cm) x v + R I R^T w
  Vec3 centre_of_mass = Vec3::Zero();  ///< m
  double mass = 0.0;                   ///< kg, of the grains
};

/// The grains' momenta (walls left out): what a run conserves without walls and external fields.
GrainMomenta grain_momenta(const Model& model, const State& state);

/// Which gravity the potential energy is measured in (the run's own gravity).
struct PotentialSettings {
  enum class Kind {
    none,     ///< no gravity: the potential energy is 0
    uniform,  ///< uniform field g: U = -sum_i m_i g . x_i
    self,     ///< self-gravity of point masses: U = -G sum_{i<j} m_i m_j / |x_i - x_j|
  };
  Kind kind = Kind::none;                     ///< which gravity
  Vec3 acceleration = Vec3::Zero();           ///< g, m/s^2, for Kind::uniform
  double gravitational_constant = 6.674e-11;  ///< G, m^3 kg^-1 s^-2, for Kind::self
  double softening = 0.0;                     ///< Plummer length eps, m (|x|^2 + eps^2 under the root)
};

/// Gravitational potential energy of the grains, J (see PotentialSettings). The self-energy of
/// each grain (constant) is left out. Self-gravity is summed exactly (O(N^2), in a fixed order).
double potential_energy(const Model& model, const State& state, const PotentialSettings& settings);

/// Settings of the contact-based metrics.
struct ContactMetricsOptions {
  /// A contact point carries force when its normal impulse r_n exceeds this (N s). 0 means any
  /// strictly positive impulse.
  double impulse_threshold = 0.0;
};

/// Sizes of each grain that depend on its shape only, so they are computed once per model, not
/// per snapshot (grain_sizes()). Indexed by body; walls get 0.
struct GrainSizes {
  /// m, diameter of the grain's circumscribed sphere, the smallest ball enclosing it: 2 r for a
  /// sphere; for a polyhedron the smallest ball enclosing its vertices (CGAL), as the accretion
  /// study measures its grains. Not twice the bounding radius about the centroid
  /// (Model::bounding_radius), which is larger for a grain whose centroid is not the ball's centre.
  std::vector<double> circumscribed_diameter;
  std::vector<double> equivalent_diameter;  ///< m, (6 V / pi)^(1/3): the sphere of the grain's volume
};

/// The grain sizes of a model: one smallest-enclosing-ball computation per polyhedron shape.
GrainSizes grain_sizes(const Model& model);

/// The metrics of one snapshot (docs/postprocessing.md gives each formula).
struct AggregateMetrics {
  double time = 0.0;        ///< s
  std::int64_t step = 0;    ///< steps taken
  std::int64_t grains = 0;  ///< N_p, bodies that are grains (walls excluded)

  // --- energies and momenta (grains only) ---
  double kinetic_energy = 0.0;          ///< J, sum of translation + rotation
  double mean_kinetic_energy = 0.0;     ///< <E_c>, J per grain
  double translational_energy = 0.0;    ///< J, sum 1/2 m v^2
  double rotational_energy = 0.0;       ///< J, sum 1/2 w.Iw
  double potential_energy = 0.0;        ///< J, gravitational (PotentialSettings)
  double total_energy = 0.0;            ///< J, kinetic + potential
  Vec3 linear_momentum = Vec3::Zero();  ///< kg m/s, sum m v
  Vec3 angular_momentum =
      Vec3::Zero();  ///< kg m^2/s, about the grains' centre of mass: sum m (x - x_cm) x v + R I R^T w

  // --- geometry ---
  Vec3 centre_of_mass = Vec3::Zero();  ///< m, of the grains
  /// D_max, m: diameter of the smallest sphere centred on x_cm that holds every grain whole,
  /// 2 max over grains of the farthest surface point from x_cm (|x_i - x_cm| + r_i for a sphere,
  /// the farthest vertex for a polyhedron).
  double aggregate_diameter = 0.0;
  double mean_diameter = 0.0;        ///< <d> = mean circumscribed-sphere diameter (GrainSizes), m
  double equivalent_diameter = 0.0;  ///< d* = mean of (6 V_i / pi)^(1/3), m
  double grain_volume = 0.0;         ///< sum V_i, m^3
  double packing_fraction = 0.0;     ///< nu = sum V_i / (pi D_max^3 / 6)
  double inner_packing_fraction =
      0.0;                        ///< grain volume inside the sphere of diameter D_max/2 about x_cm, over its volume
  std::int64_t inner_grains = 0;  ///< grains whose centre is inside that inner sphere
  /// Semi-axes s_1 >= s_2 >= s_3 of the inertia-equivalent ellipsoid, m: the uniform solid
  /// ellipsoid with the grains' total mass M and inertia tensor I about x_cm (grains' own inertia
  /// included), s_i^2 = 5 (I_j + I_k - I_i) / (2 M) over the principal moments I_i.
  Vec3 inertia_semi_axes = Vec3::Zero();
  double inertia_aspect_ratio = 0.0;  ///< s_1 / s_3, elongation of the aggregate (1 for a ball)
  double inertia_diameter = 0.0;      ///< D_I = 2 (s_1 s_2 s_3)^(1/3), m: the sphere of the ellipsoid's volume
  double inertia_packing_fraction =
      0.0;  ///< nu_I = sum V_i / (4/3 pi s_1 s_2 s_3): bulk packing fraction of the aggregate

  // --- contacts ---
  std::int64_t contact_points = 0;        ///< contact points in the list (any impulse)
  std::int64_t force_bearing_points = 0;  ///< points with r_n > threshold (grain-grain and grain-wall)
  std::int64_t sliding_points = 0;        ///< force-bearing points whose status is sliding
  double sliding_fraction = 0.0;          ///< sliding_points / force_bearing_points (0 if none)
  std::int64_t grain_contacts = 0;        ///< N_c: grain pairs touching through >= 1 force-bearing point
  std::int64_t wall_contacts = 0;         ///< grain-wall pairs touching through >= 1 force-bearing point
  double coordination = 0.0;              ///< Z = 2 N_c / N_p
  /// Grains with fewer than 2 force-bearing contacts with bodies that are not rattlers (walls
  /// count), found iteratively until none is left
  std::int64_t rattlers = 0;
  double coordination_without_rattlers = 0.0;  ///< Z' = 2 N_c' / N_p' over the non-rattlers
  double inner_coordination = 0.0;             ///< mean grain-grain contacts of the inner grains (bulk Z)
  double mean_normal_impulse = 0.0;            ///< N s, mean r_n over force-bearing points
  double max_normal_impulse = 0.0;             ///< N s, largest r_n
  double max_overlap = 0.0;                    ///< m, deepest interpenetration, max(0, -gap) over the contact points
  /// Grains outside the largest cluster of the contact network (edges: the grain-grain contact
  /// points of the list, i.e. pairs within the detection's alert distance, any impulse).
  std::int64_t detached_grains = 0;
  /// Detached grains on an escape orbit: 1/2 |v_i - v_cm|^2 + phi_i > 0, phi_i the exact
  /// self-gravity potential of all other grains at grain i. Counted only with
  /// PotentialSettings::Kind::self (0 otherwise).
  std::int64_t escaping_grains = 0;
};

/// Every metric of one snapshot. `contacts` are the snapshot's contact points; `sizes` are
/// grain_sizes(model), computed once for a series of snapshots of one model.
AggregateMetrics compute_metrics(const Model& model, const GrainSizes& sizes, const State& state,
                                 const ContactList& contacts, const PotentialSettings& potential = {},
                                 const ContactMetricsOptions& options = {});

/// The same, computing grain_sizes(model) first (one snapshot on its own).
AggregateMetrics compute_metrics(const Model& model, const State& state, const ContactList& contacts,
                                 const PotentialSettings& potential = {}, const ContactMetricsOptions& options = {});

/// Force-bearing grain-grain contacts of each body (pairs, not points); walls get 0. What Z is
/// built from; exposed for per-grain output (VTK) and tests.
std::vector<int> grain_contact_counts(const Model& model, const ContactList& contacts,
                                      const ContactMetricsOptions& options = {});

/// Histogram of r_n / <r_n> over the force-bearing contact points: `bins` equal bins over
/// [0, upper] (upper = max r_n / <r_n>, rounded up to an integer); empty if no point carries force.
struct ImpulseHistogram {
  std::vector<double> bin_lower;     ///< lower edge of each bin (in units of the mean)
  std::vector<double> bin_upper;     ///< upper edge of each bin
  std::vector<std::int64_t> count;   ///< points per bin
  std::vector<double> density;       ///< probability density: count / (total * width)
  double mean_normal_impulse = 0.0;  ///< <r_n>, N s
};
/// The normal impulse distribution of one snapshot.
ImpulseHistogram normal_impulse_histogram(const ContactList& contacts, int bins = 20,
                                          const ContactMetricsOptions& options = {});

/// Names of the scalar columns of metrics_row(), in order (the CSV header and HDF5 dataset names).
std::vector<std::string> metrics_column_names();
/// The metrics as one row of numbers, in the order of metrics_column_names() (vectors as x, y, z).
std::vector<double> metrics_row(const AggregateMetrics& metrics);

}  // namespace rubble
