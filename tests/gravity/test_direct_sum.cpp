// Tests of the exact direct sum (gravity/direct_sum.cpp): against an independent scalar sum, the
// two-body problem, softening, Newton's third law, determinism and input validation.

#include "gravity/direct_sum.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <numeric>
#include <vector>

#include "gravity/gravity.hpp"
#include "test_support.hpp"

namespace g = rubble::gravity;
using g::testing::Particles;

namespace {

/// Independent reference: plain scalar double loop, written without the library kernel.
void naive_field(const Particles& p, double G, double eps, std::vector<double>& a, std::vector<double>& phi) {
  const std::size_t n = p.size();
  a.assign(3 * n, 0.0);
  phi.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      if (i == j) continue;
      double d[3], r2 = eps * eps;
      for (int c = 0; c < 3; ++c) {
        d[c] = p.pos[3 * j + c] - p.pos[3 * i + c];
        r2 += d[c] * d[c];
      }
      const double r = std::sqrt(r2);
      for (int c = 0; c < 3; ++c) a[3 * i + c] += G * p.mass[j] * d[c] / (r2 * r);
      phi[i] -= G * p.mass[j] / r;
    }
}

std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3e", v);
  return buf;
}

g::GravityOptions direct_options(double G = 6.674e-11) {
  g::GravityOptions o;
  o.method = g::Method::direct;
  o.G = G;
  return o;
}

}  // namespace

TEST(DirectSum, MatchesIndependentScalarSum) {
  const Particles p = g::testing::uniform_sphere(257, 10.0, 1e9, 1);
  std::vector<double> a(3 * p.size()), phi(p.size()), ra, rphi;
  g::compute_field(direct_options(), p.pos, p.mass, a, phi);
  naive_field(p, 6.674e-11, 0.0, ra, rphi);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double amag = std::hypot(ra[3 * i], ra[3 * i + 1], ra[3 * i + 2]);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[3 * i + c], ra[3 * i + c], 1e-12 * amag);
    EXPECT_NEAR(phi[i], rphi[i], 1e-12 * std::abs(rphi[i]));
  }
}

TEST(DirectSum, PlummerSofteningMatchesFormula) {
  const Particles p = g::testing::uniform_sphere(100, 1.0, 1.0, 2);
  auto o = direct_options(1.0);
  o.softening = {g::Softening::Kind::plummer, 0.05};
  std::vector<double> a(3 * p.size()), phi(p.size()), ra, rphi;
  g::compute_field(o, p.pos, p.mass, a, phi);
  naive_field(p, 1.0, 0.05, ra, rphi);
  for (std::size_t i = 0; i < 3 * p.size(); ++i) EXPECT_NEAR(a[i], ra[i], 1e-12 * std::abs(ra[i]) + 1e-14);
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_NEAR(phi[i], rphi[i], 1e-12 * std::abs(rphi[i]));

  // Two bodies at distance d: |a| = G m d / (d^2 + eps^2)^{3/2}, phi = -G m / sqrt(d^2 + eps^2).
  const std::vector<double> pos{0, 0, 0, 3, 0, 0}, m{2.0, 5.0};
  std::vector<double> a2(6), phi2(2);
  o.softening.length = 4.0;
  g::compute_field(o, pos, m, a2, phi2);
  EXPECT_DOUBLE_EQ(a2[0], 5.0 * 3.0 / 125.0);
  EXPECT_DOUBLE_EQ(a2[3], -2.0 * 3.0 / 125.0);
  EXPECT_DOUBLE_EQ(phi2[0], -5.0 / 5.0);
  EXPECT_DOUBLE_EQ(phi2[1], -2.0 / 5.0);
}

TEST(DirectSum, SingleParticleFeelsNothingAndMomentumIsConserved) {
  const std::vector<double> one_pos{1, 2, 3}, one_m{7};
  std::vector<double> a(3, 1.0), phi(1, 1.0);
  g::compute_field(direct_options(), one_pos, one_m, a, phi);
  EXPECT_EQ(a, std::vector<double>(3, 0.0));
  EXPECT_EQ(phi[0], 0.0);

  // Newton's third law: sum_i m_i a_i = 0 up to rounding.
  const Particles p = g::testing::plummer_sphere(1000, 1.0, 1.0, 3);
  std::vector<double> acc(3 * p.size());
  g::compute_field(direct_options(1.0), p.pos, p.mass, acc, {});
  double total[3] = {0, 0, 0}, scale = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      total[c] += p.mass[i] * acc[3 * i + c];
      scale += p.mass[i] * std::abs(acc[3 * i + c]);
    }
  for (double t : total) EXPECT_LT(std::abs(t), 1e-13 * scale);
}

TEST(DirectSum, TargetsSubsetMatchesFullSum) {
  const Particles p = g::testing::uniform_sphere(500, 1.0, 1.0, 4);
  std::vector<double> a(3 * p.size()), phi(p.size());
  g::direct_sum(direct_options(), p.pos, p.mass, a, phi);
  const std::vector<std::size_t> targets{0, 17, 499, 17};
  std::vector<double> at(3 * targets.size()), phit(targets.size());
  g::direct_sum_targets(direct_options(), p.pos, p.mass, targets, at, phit);
  for (std::size_t k = 0; k < targets.size(); ++k) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(at[3 * k + c], a[3 * targets[k] + c]);
    EXPECT_EQ(phit[k], phi[targets[k]]);
  }
}

TEST(DirectSum, BitIdenticalForOneAndTwoThreads) {
  const Particles p = g::testing::plummer_sphere(3000, 1.0, 1.0, 5);
  std::vector<double> a1(3 * p.size()), a2(3 * p.size()), f1(p.size()), f2(p.size());
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  g::compute_field(direct_options(), p.pos, p.mass, a1, f1);
  omp_set_num_threads(2);
  g::compute_field(direct_options(), p.pos, p.mass, a2, f2);
  omp_set_num_threads(saved);
  EXPECT_EQ(std::memcmp(a1.data(), a2.data(), a1.size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(f1.data(), f2.data(), f1.size() * sizeof(double)), 0);
}

TEST(DirectSum, RejectsInvalidInput) {
  std::vector<double> pos{0, 0, 0, 1, 0, 0}, m{1, 1}, a(6), phi(2);
  EXPECT_THROW(g::compute_field(direct_options(), std::vector<double>(5), m, a, phi), g::GravityError);
  std::vector<double> a5(5), phi3(3);
  EXPECT_THROW(g::compute_field(direct_options(), pos, m, a5, phi), g::GravityError);
  EXPECT_THROW(g::compute_field(direct_options(), pos, m, a, phi3), g::GravityError);
  std::vector<double> bad_m{1, -1};
  EXPECT_THROW(g::compute_field(direct_options(), pos, bad_m, a, phi), g::GravityError);
  bad_m[1] = std::nan("");
  EXPECT_THROW(g::compute_field(direct_options(), pos, bad_m, a, phi), g::GravityError);
  auto o = direct_options();
  o.softening = {g::Softening::Kind::plummer, -1.0};
  EXPECT_THROW(g::compute_field(o, pos, m, a, phi), g::GravityError);
  // Potential is optional.
  EXPECT_NO_THROW(g::compute_field(direct_options(), pos, m, a, {}));
}

// The input check runs as one pass on all threads for large N (gravity.cpp,
// all_finite_and_masses_non_negative) and only then looks for the culprit: one bad value among
// 300 000 particles is still found and named, and -0.0 is still a valid mass.
TEST(DirectSum, InputCheckFindsOneBadValueInALargeInput) {
  const std::size_t n = 300000;
  std::vector<double> pos(3 * n, 1.0), m(n, 1.0);
  const g::GravityOptions o = direct_options();
  EXPECT_NO_THROW(g::validate_particles(o, pos, m));
  m[17] = -0.0;
  EXPECT_NO_THROW(g::validate_particles(o, pos, m));
  auto message = [&](const std::vector<double>& x, const std::vector<double>& mass) -> std::string {
    try {
      g::validate_particles(o, x, mass);
    } catch (const g::GravityError& e) {
      return e.what();
    }
    return "accepted";
  };
  for (double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL}) {
    auto x = pos;
    x[3 * (n - 2) + 1] = bad;
    EXPECT_EQ(message(x, m), "position " + std::to_string(n - 2) + " is not finite") << bad;
  }
  for (double bad : {-1e-300, std::nan(""), HUGE_VAL}) {
    auto mass = m;
    mass[n - 1] = bad;
    EXPECT_EQ(message(pos, mass), "mass " + std::to_string(n - 1) + " is not a finite number >= 0") << bad;
  }
}

// Two bodies on a circular orbit, integrated with velocity Verlet (kick-drift-kick) at 1000 steps
// per orbit for 10 orbits in SI units with the default G. Kepler: T = 2 pi sqrt(a^3 / (G M)).
TEST(DirectSum, TwoBodyCircularOrbit) {
  const double G = 6.674e-11, m1 = 1.0e12, m2 = 4.0e11, M = m1 + m2, sep = 1000.0;
  const double T = 2.0 * M_PI * std::sqrt(sep * sep * sep / (G * M));
  const double v = std::sqrt(G * M / sep);  // relative speed on the circular orbit
  std::vector<double> x{-m2 / M * sep, 0, 0, m1 / M * sep, 0, 0};
  std::vector<double> vel{0, -m2 / M * v, 0, 0, m1 / M * v, 0};
  const std::vector<double> m{m1, m2};
  std::vector<double> a(6), phi(2);
  const auto o = direct_options(G);

  auto energy = [&] {
    double e = 0;
    for (int i = 0; i < 2; ++i) {
      const double v2 = vel[3 * i] * vel[3 * i] + vel[3 * i + 1] * vel[3 * i + 1] + vel[3 * i + 2] * vel[3 * i + 2];
      e += 0.5 * m[i] * v2 + 0.5 * m[i] * phi[i];  // U = (1/2) sum_i m_i phi_i
    }
    return e;
  };
  auto angular_momentum_z = [&] {
    double l = 0;
    for (int i = 0; i < 2; ++i) l += m[i] * (x[3 * i] * vel[3 * i + 1] - x[3 * i + 1] * vel[3 * i]);
    return l;
  };
  auto angle = [&] { return std::atan2(x[4] - x[1], x[3] - x[0]); };

  const int steps_per_orbit = 1000, orbits = 10;
  const double dt = T / steps_per_orbit;
  g::compute_field(o, x, m, a, phi);
  const double e0 = energy(), l0 = angular_momentum_z();
  // Analytic energy of the circular orbit: E = -G m1 m2 / (2 sep).
  EXPECT_NEAR(e0, -G * m1 * m2 / (2 * sep), 1e-12 * std::abs(e0));

  double unwrapped = angle(), previous = angle(), crossing_time = -1;
  const double target_angle = unwrapped + 2.0 * M_PI * orbits;
  double max_de_per_orbit = 0, max_dl_per_orbit = 0;
  for (int s = 1; s <= steps_per_orbit * (orbits + 1); ++s) {
    for (int i = 0; i < 6; ++i) vel[i] += 0.5 * dt * a[i];
    for (int i = 0; i < 6; ++i) x[i] += dt * vel[i];
    g::compute_field(o, x, m, a, phi);
    for (int i = 0; i < 6; ++i) vel[i] += 0.5 * dt * a[i];
    const double now = angle();
    const double before = unwrapped;
    unwrapped += std::remainder(now - previous, 2.0 * M_PI);
    previous = now;
    if (crossing_time < 0 && unwrapped >= target_angle)  // linear interpolation within the step
      crossing_time = dt * (s - 1 + (target_angle - before) / (unwrapped - before));
    if (s % steps_per_orbit == 0 && s <= steps_per_orbit * orbits) {
      const double k = s / steps_per_orbit;
      max_de_per_orbit = std::max(max_de_per_orbit, std::abs((energy() - e0) / e0) / k);
      max_dl_per_orbit = std::max(max_dl_per_orbit, std::abs((angular_momentum_z() - l0) / l0) / k);
    }
  }
  ASSERT_GT(crossing_time, 0);
  const double period = crossing_time / orbits;
  RecordProperty("period_relative_error", sci(std::abs(period - T) / T));
  RecordProperty("energy_drift_per_orbit", sci(max_de_per_orbit));
  RecordProperty("angular_momentum_drift_per_orbit", sci(max_dl_per_orbit));
  EXPECT_LT(std::abs(period - T) / T, 1e-3);
  EXPECT_LT(max_de_per_orbit, 1e-6);
  EXPECT_LT(max_dl_per_orbit, 1e-6);
}
