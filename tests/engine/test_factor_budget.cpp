// FactorBudget: cached factorizations charged to one byte budget, evicted least recently
// used across sets, rebuilt on demand with the same bits.
#include "fixtures.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace hdeform {
namespace {

using test::Benchmark;

Beta raw(double b) { return {b, BetaUnits::raw}; }

HandleTransform lift() {
  HandleTransform h;
  h.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitX()));
  h.translation = Eigen::Vector3d(0, 0.3, 0.1);
  return h;
}

const Benchmark& capsule() {
  static const Benchmark b = test::capsule_benchmark(3000);
  return b;
}

// The bytes one β > 0 system of the capsule takes (measured on a set of its own).
std::size_t beta_system_bytes() {
  const Benchmark& b = capsule();
  ConstraintSet cs(b.mesh, b.constraints);
  cs.prepare(raw(0.2));  // builds the β > 0 blocks too
  const std::size_t one = cs.memory_bytes();
  cs.prepare(raw(0.3));
  return cs.memory_bytes() - one;
}

std::size_t beta0_bytes() {
  const Benchmark& b = capsule();
  auto cs = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  auto budget = std::make_shared<FactorBudget>(std::size_t{1} << 40);
  cs->charge_to(budget);
  return budget->stats().charged;
}

TEST(FactorBudget, DistinctBetasStayWithinTheLimit) {
  const Benchmark& b = capsule();
  const std::size_t per_beta = beta_system_bytes();
  const std::size_t limit = beta0_bytes() + 3 * per_beta + per_beta / 2;
  auto budget = std::make_shared<FactorBudget>(limit);
  auto cs = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  cs->charge_to(budget);
  const std::vector<HandleTransform> t{lift()};
  for (int k = 1; k <= 12; ++k) {
    cs->update(t, raw(0.05 * k));
    const FactorBudget::Stats s = budget->stats();
    EXPECT_LE(s.charged, limit) << "beta " << 0.05 * k;
    EXPECT_LE(cs->num_cached_factorizations(), 4u) << "beta 0 and three others at most";
  }
  EXPECT_GE(budget->stats().evictions, 8u);
  EXPECT_TRUE(cs->is_cached(raw(0))) << "beta 0 is pinned: the harmonic basis came from it";
  EXPECT_TRUE(cs->is_cached(raw(0.05 * 12))) << "the most recent beta stays";
  EXPECT_FALSE(cs->is_cached(raw(0.05))) << "the oldest went first";
}

TEST(FactorBudget, EvictsTheLeastRecentlyUsedAcrossSets) {
  const Benchmark& b = capsule();
  const std::size_t per_beta = beta_system_bytes();
  // Two sets' β = 0 systems plus two β > 0 systems fit; a third evicts one.
  auto budget = std::make_shared<FactorBudget>(2 * beta0_bytes() + 2 * per_beta + per_beta / 2);
  auto a = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  auto c = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  a->charge_to(budget);
  c->charge_to(budget);
  const std::vector<HandleTransform> t{lift()};
  a->update(t, raw(0.1));
  c->update(t, raw(0.2));
  a->update(t, raw(0.1));  // a's β = 0.1 is now the more recent
  c->update(t, raw(0.3));  // over the limit: c's 0.2 (least recently used) goes
  EXPECT_TRUE(a->is_cached(raw(0.1)));
  EXPECT_FALSE(c->is_cached(raw(0.2)));
  EXPECT_TRUE(c->is_cached(raw(0.3)));
}

TEST(FactorBudget, ARebuiltBetaGivesTheSameBits) {
  const Benchmark& b = capsule();
  const std::vector<HandleTransform> t{lift()};
  auto fresh = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  const Frame expected = fresh->update(t, raw(0.25));

  auto budget = std::make_shared<FactorBudget>(beta0_bytes() + beta_system_bytes() / 2);
  auto cs = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  cs->charge_to(budget);
  EXPECT_TRUE(test::same_bits(cs->update(t, raw(0.25)).positions, expected.positions));
  cs->update(t, raw(0.4));  // evicts 0.25 (nothing but the newest fits)
  ASSERT_FALSE(cs->is_cached(raw(0.25)));
  EXPECT_TRUE(test::same_bits(cs->update(t, raw(0.25)).positions, expected.positions));
}

TEST(FactorBudget, TransientAndDestroyedSystemsAreNoLongerCharged) {
  const Benchmark& b = capsule();
  auto budget = std::make_shared<FactorBudget>(std::size_t{1} << 40);
  const std::vector<HandleTransform> t{lift()};
  {
    auto cs = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
    cs->charge_to(budget);
    const std::size_t open = budget->stats().charged;
    EXPECT_GT(open, 0u);
    cs->update_transient(t, raw(0.35));
    EXPECT_EQ(budget->stats().charged, open) << "a transient system is freed on return";
    cs->update(t, raw(0.35));
    EXPECT_GT(budget->stats().charged, open);
  }
  EXPECT_EQ(budget->stats().charged, 0u) << "a destroyed set's systems are gone";
}

TEST(FactorBudget, ConcurrentUpdatesAndEvictionsAgree) {
  const Benchmark& b = capsule();
  const std::vector<HandleTransform> t{lift()};
  auto fresh = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  std::vector<Frame> expected;
  for (int k = 0; k < 4; ++k) expected.push_back(fresh->update(t, raw(0.1 + 0.1 * k)));

  auto budget = std::make_shared<FactorBudget>(beta0_bytes() + beta_system_bytes());
  auto cs = std::make_shared<ConstraintSet>(b.mesh, b.constraints);
  cs->charge_to(budget);
  std::vector<std::thread> threads;
  std::vector<int> wrong(2, 0);
  for (int id = 0; id < 2; ++id)
    threads.emplace_back([&, id] {
      for (int i = 0; i < 8; ++i) {
        const int k = (i + id) % 4;
        if (!test::same_bits(cs->update(t, raw(0.1 + 0.1 * k)).positions,
                             expected[static_cast<std::size_t>(k)].positions))
          ++wrong[static_cast<std::size_t>(id)];
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong[0] + wrong[1], 0);
  EXPECT_LE(cs->num_cached_factorizations(), 3u);
}

TEST(FactorBudget, ChargeToNeedsASharedSet) {
  const Benchmark& b = capsule();
  ConstraintSet on_stack(b.mesh, b.constraints);
  EXPECT_THROW(on_stack.charge_to(std::make_shared<FactorBudget>(1)), std::logic_error);
}

}  // namespace
// Work that may wait (a background order) is charged only where it fits, evicts nothing,
// counts against later charges while it lives and stops counting when it is gone.
TEST(FactorBudget, ChargeIfRoomNeverEvicts) {
  struct Item : FactorBudget::Item {};
  struct Owner : FactorBudget::Owner {
    mutable int evicted = 0;
    void evict(const FactorBudget::Item&) const override { ++evicted; }
  };
  std::size_t other = 10;
  auto budget = std::make_shared<FactorBudget>(100, [&] { return other; });
  const auto owner = std::make_shared<const Owner>();
  const auto cached = std::make_shared<const Item>();
  budget->charge(owner, cached, 50, /*pinned=*/false);
  auto working = std::make_shared<const Item>();
  EXPECT_FALSE(budget->charge_if_room(working, 41)) << "10 + 50 + 41 > 100";
  EXPECT_EQ(budget->stats().charged, 50u);
  EXPECT_TRUE(budget->charge_if_room(working, 40));
  EXPECT_EQ(budget->stats().charged, 90u);
  EXPECT_EQ(budget->stats().pinned, 40u);
  EXPECT_FALSE(budget->charge_if_room(std::make_shared<const Item>(), 1)) << "full";
  other = 200;  // the cache's own entries grew past the limit
  working.reset();
  EXPECT_FALSE(budget->charge_if_room(std::make_shared<const Item>(), 0)) << "over already";
  EXPECT_EQ(owner->evicted, 0);
  EXPECT_EQ(budget->stats().evictions, 0u);
  EXPECT_EQ(budget->stats().charged, 50u) << "the working item's charge ends with it";
}

}  // namespace hdeform
