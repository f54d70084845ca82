// Broad phase against brute force, determinism, and the warm-start matching.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "contact_detection/detection.hpp"

namespace rubble {
namespace {

struct Cloud {
  Model model;
  State state;
};

// n spheres with radii uniform in [r_min, r_max] scattered in a cube of side `side`.
Cloud random_cloud(int n, double r_min, double r_max, double side, std::uint64_t seed) {
  Cloud c;
  c.model.materials.push_back({"rock", 2000});
  c.model.contact_laws.reset(1, {});
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> radius(r_min, r_max), coordinate(0.0, side);
  for (int k = 0; k < n; ++k) add_sphere(c.model, radius(rng), 0);
  c.state.resize(c.model.body_count());
  for (auto& p : c.state.position) p = Vec3(coordinate(rng), coordinate(rng), coordinate(rng));
  return c;
}

std::vector<BodyPair> brute_force_pairs(const Cloud& c, double alert) {
  std::vector<BodyPair> pairs;
  for (std::uint32_t a = 0; a < c.model.body_count(); ++a)
    for (std::uint32_t b = a + 1; b < c.model.body_count(); ++b) {
      const double reach = c.model.bounding_radius[a] + c.model.bounding_radius[b] + alert;
      if ((c.state.position[a] - c.state.position[b]).norm() < reach) pairs.push_back({a, b});
    }
  return pairs;
}

// Every pair within reach must be a candidate (the broad phase may add box-corner pairs), and the
// candidates are sorted, each pair once.
::testing::AssertionResult sorted_superset(const std::vector<BodyPair>& candidates,
                                           const std::vector<BodyPair>& needed) {
  if (!std::is_sorted(candidates.begin(), candidates.end())) return ::testing::AssertionFailure() << "not sorted";
  if (const auto twice = std::adjacent_find(candidates.begin(), candidates.end()); twice != candidates.end()) {
    return ::testing::AssertionFailure() << "duplicate pair " << twice->body_a << "-" << twice->body_b;
  }
  for (const BodyPair& p : needed) {
    if (!std::binary_search(candidates.begin(), candidates.end(), p)) {
      return ::testing::AssertionFailure() << "missing pair " << p.body_a << "-" << p.body_b;
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(BroadPhase, FindsEveryPairOfAPolydisperseCloud) {
  const Cloud c = random_cloud(3000, 3.75, 5.0, 150.0, 1);  // the study's 7.5-10 m diameters
  EXPECT_TRUE(sorted_superset(find_candidate_pairs(c.model, c.state, 0.2), brute_force_pairs(c, 0.2)));
}

TEST(BroadPhase, FindsEveryPairWithATenToOneSizeRatio) {
  const Cloud c = random_cloud(3000, 0.1, 1.0, 20.0, 2);
  const auto needed = brute_force_pairs(c, 0.01);
  const auto candidates = find_candidate_pairs(c.model, c.state, 0.01);
  EXPECT_TRUE(sorted_superset(candidates, needed));
  // Candidates are pairs of overlapping boxes: at most (6/pi) times the pairs of overlapping spheres.
  EXPECT_LT(candidates.size(), 3 * needed.size() + 10);
}

// Few grains mean few hash buckets, so the many cells of one large grain share buckets: each pair
// must still be reported once (a duplicated contact doubles a constraint and stalls the solver).
TEST(BroadPhase, NoDuplicatePairsWhenCellsShareABucket) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const Cloud c = random_cloud(4, 0.05, 1.0, 1.5, seed);
    const auto candidates = find_candidate_pairs(c.model, c.state, 0.01);
    EXPECT_TRUE(sorted_superset(candidates, brute_force_pairs(c, 0.01)));
  }
}

TEST(Detection, ContactsAreSortedAndTheirGapsAreTheSpheresDistance) {
  Cloud c = random_cloud(500, 0.5, 1.0, 12.0, 3);
  DetectionMemory memory;
  const ContactList contacts = detect_contacts(c.model, c.state, DetectionOptions{0.05}, memory);
  ASSERT_FALSE(contacts.empty());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    const Contact& x = contacts[k];
    if (k > 0) {
      EXPECT_LT(contacts[k - 1].id, x.id);
    }
    const double distance = (c.state.position[x.id.body_b] - c.state.position[x.id.body_a]).norm();
    EXPECT_NEAR(x.gap, distance - c.model.bounding_radius[x.id.body_a] - c.model.bounding_radius[x.id.body_b], 1e-12);
    EXPECT_LT(x.gap, 0.05);
    EXPECT_NEAR((x.frame.transpose() * x.frame - Mat3::Identity()).norm(), 0.0, 1e-12);
    EXPECT_NEAR(x.frame.determinant(), 1.0, 1e-12);
  }
  EXPECT_EQ(contacts.size(), brute_force_pairs(c, 0.05).size());
}

// The Verlet pair list (DetectionOptions::pair_list_margin) must not change a single contact.
// Reference: a broad phase at every step (margin 0), on a cloud whose grains random-walk by up to
// 0.2 alert distances a step for 300 steps; the list must also have been reused most steps.
TEST(Detection, PairListGivesTheContactsOfABroadPhaseEveryStep) {
  Cloud c = random_cloud(400, 0.5, 1.0, 10.0, 5);
  const double alert = 0.05;
  DetectionOptions every_step{alert};
  every_step.pair_list_margin = 0.0;
  const DetectionOptions with_list{alert};  // automatic margin: the alert distance
  DetectionMemory memory_every, memory_list;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> step(-0.2 * alert / std::sqrt(3.0), 0.2 * alert / std::sqrt(3.0));
  int reused = 0;
  std::size_t checked = 0;
  for (int k = 0; k < 300; ++k) {
    DetectionStats stats;
    const ContactList reference = detect_contacts(c.model, c.state, every_step, memory_every);
    const ContactList listed = detect_contacts(c.model, c.state, with_list, memory_list, &stats);
    if (!stats.pair_list_rebuilt) ++reused;
    ASSERT_EQ(listed.size(), reference.size()) << "step " << k;
    for (std::size_t i = 0; i < listed.size(); ++i) {
      ASSERT_EQ(listed[i].id, reference[i].id) << "step " << k;
      ASSERT_EQ(listed[i].gap, reference[i].gap) << "step " << k;
    }
    checked += listed.size();
    for (auto& p : c.state.position) p += Vec3(step(rng), step(rng), step(rng));
  }
  EXPECT_GT(checked, 1000u);
  EXPECT_GT(reused, 150);  // half a margin = 2.5 walks of 0.2 alert at most: rebuilt every few steps
}

// The narrow phase runs in waves of pairs and the list is re-sorted through an index permutation
// when pairs interleave; neither may change a bit. Reference: every brute-force pair collided on
// its own and the whole list stable-sorted by id. Over 4 096 pairs (several waves), and a floor
// numbered after the grains, so that its contacts (body a = the floor) need the global sort.
TEST(Detection, WavesAndTheGlobalSortGiveThePairByPairList) {
  Cloud c = random_cloud(6000, 0.5, 1.0, 30.0, 7);
  const int floor = add_plane_wall(c.model, Vec3(0, 0, 1), 0);
  c.state.position.push_back(Vec3(0, 0, 2.0));
  c.state.orientation.push_back(Quat::Identity());
  c.state.velocity.push_back(Vec3::Zero());
  c.state.angular_velocity.push_back(Vec3::Zero());
  ASSERT_EQ(c.state.body_count(), c.model.body_count());
  const double alert = 0.05;
  DetectionMemory memory;
  DetectionStats stats;
  const ContactList contacts = detect_contacts(c.model, c.state, DetectionOptions{alert}, memory, &stats);
  ASSERT_GT(stats.candidate_pairs, 2 * 4096u);

  std::vector<BodyPair> pairs = brute_force_pairs(c, alert);  // sphere pairs (the plane's radius is infinite:
  pairs.erase(std::remove_if(pairs.begin(), pairs.end(),      // brute force lists it with everything)
                             [&](const BodyPair& p) { return p.body_b == static_cast<std::uint32_t>(floor); }),
              pairs.end());
  for (std::uint32_t b = 0; b < static_cast<std::uint32_t>(floor); ++b)
    pairs.push_back({b, static_cast<std::uint32_t>(floor)});
  ContactList reference;
  Vec3 unused_normal;
  for (const BodyPair& p : pairs) collide_pair(c.model, c.state, p, alert, DetectionMemory{}, reference, unused_normal);
  std::stable_sort(reference.begin(), reference.end(), [](const Contact& x, const Contact& y) { return x.id < y.id; });

  std::size_t floor_contacts = 0;
  for (const Contact& x : reference) floor_contacts += x.id.body_a == static_cast<std::uint32_t>(floor) ? 1 : 0;
  ASSERT_GT(floor_contacts, 10u);
  ASSERT_EQ(contacts.size(), reference.size());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    ASSERT_EQ(contacts[k].id, reference[k].id) << k;
    ASSERT_EQ(contacts[k].gap, reference[k].gap) << k;
    ASSERT_EQ(contacts[k].point, reference[k].point) << k;
    ASSERT_EQ(contacts[k].frame, reference[k].frame) << k;
  }
}

TEST(MatchContacts, CarriesTheWorldImpulseIntoTheNewFrame) {
  Contact old_contact;
  old_contact.id = {1, 2, 0, 0};
  old_contact.frame = frame_from_normal(Vec3(0, 0, 1));
  old_contact.impulse = Vec3(2.0, 0.5, -0.25);
  Contact new_contact = old_contact;
  new_contact.frame = frame_from_normal(Vec3(0.1, 0, 1).normalized());
  new_contact.impulse = Vec3::Zero();
  Contact unmatched;
  unmatched.id = {1, 3, 0, 0};
  ContactList current{new_contact, unmatched};
  carry_impulses({old_contact}, current);
  EXPECT_LT((current[0].frame * current[0].impulse - old_contact.frame * old_contact.impulse).norm(), 1e-14);
  EXPECT_EQ(current[1].impulse, Vec3::Zero());
}

// Warm start from the 40-byte records (last step's list freed before detection) must give the
// impulses of the full-list expression frame_new^T (frame_old r_old) to the bit.
TEST(MatchContacts, RecordsCarryTheFullListsImpulsesToTheBit) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  ContactList previous, current;
  for (std::uint32_t b = 1; b < 400; ++b) {
    Contact c;
    c.id = {b / 3, b, b % 2, 0};
    c.frame = frame_from_normal(Vec3(u(rng), u(rng), u(rng)).normalized());
    c.impulse = Vec3(u(rng), u(rng), u(rng));
    if (b % 5 != 0) previous.push_back(c);  // some contacts are new this step
    c.frame = frame_from_normal(Vec3(u(rng), u(rng), u(rng)).normalized());
    c.impulse = Vec3::Zero();
    if (b % 7 != 0) current.push_back(c);  // some have closed
  }
  const std::vector<CarriedImpulse> records = impulses_to_carry(previous);
  ASSERT_EQ(records.size(), previous.size());
  ContactList carried = current;
  carry_impulses(records, carried);
  std::size_t matched = 0;
  for (std::size_t k = 0; k < current.size(); ++k) {
    const auto old =
        std::find_if(previous.begin(), previous.end(), [&](const Contact& p) { return p.id == current[k].id; });
    const Vec3 expected =
        old == previous.end() ? Vec3::Zero() : Vec3(current[k].frame.transpose() * (old->frame * old->impulse));
    EXPECT_EQ(carried[k].impulse, expected) << k;
    matched += old == previous.end() ? 0 : 1;
  }
  EXPECT_GT(matched, 200u);
  ContactList from_list = current;
  carry_impulses(previous, from_list);
  for (std::size_t k = 0; k < current.size(); ++k) EXPECT_EQ(from_list[k].impulse, carried[k].impulse) << k;
}

}  // namespace
}  // namespace rubble
