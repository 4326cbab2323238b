// --cache-mb bounds every factorization a session makes (one per distinct β), over a real
// server on loopback: a β slider's values leave the process's RSS within the budget plus a
// constant, a β revisited after its eviction gives the same frame bits, and a deleted
// session gives its memory back.
#include "fixtures/sanitizers.h"
#include "service_fixture.h"

#include <unistd.h>

#include <fstream>

using namespace hdeform::testing;

namespace {

std::size_t rss_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::size_t pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
}

constexpr std::size_t kMiB = std::size_t{1} << 20;
// What the process may hold beyond the budget (docs/deployment.md "Memory"): pages glibc's
// per-thread arenas keep around live blocks after malloc_trim, gRPC's buffers, the frames.
// Measured peaks: 236–263 MiB after a 117 MiB open with a 160 MiB budget, one of about ten
// runs 416 MiB; without the budget the same 60 βs reach ≈ 2.4 GB.
constexpr std::size_t kSlack = 192 * kMiB;

std::string positions_at(TestServer& t, const std::string& name, std::int64_t seq) {
  pb::Frame f;
  const auto st = t.update(name, seq, {translation(0.2, 0.1, 0.3)}, &f);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return f.positions();
}

constexpr bool kMeasureRss = !HDEFORM_SANITIZED;  // the sanitizers' allocators keep freed memory

TEST(ServiceMemoryBudget, SixtyDistinctBetasStayWithinTheCacheBudget) {
  hdeform::service::ServerOptions o;
  o.cache_bytes = 160 * kMiB;
  // The β factorizations alone: a background order would race the first SetConstraints and
  // β > 0 for the same METIS call and leave its own thread's heap arena behind (its memory
  // has its own bound and test: test_background_orders.cpp).
  o.background_order_from = 0;
  TestServer t(o);
  const std::string mesh = grid_off(201);  // 40,401 vertices
  const std::size_t rss_before = rss_bytes();

  pb::Session s;
  ASSERT_TRUE(t.upload(mesh, "grid.off", &s).ok());
  ASSERT_TRUE(t.set_constraints(s.name(), grid_strips(), &s).ok());
  std::int64_t seq = 1;
  positions_at(t, s.name(), seq++);
  const std::size_t rss_open = rss_bytes();

  std::string first;
  std::size_t peak = rss_open;
  for (int k = 1; k <= 60; ++k) {
    const auto st = t.set_beta(s.name(), 0.01 * k, &s);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const std::string p = positions_at(t, s.name(), seq++);
    if (k == 1) first = p;
    peak = std::max(peak, rss_bytes());
    // What the server accounts is within the budget after every change (the pinned β = 0
    // system and the current β could exceed it alone, not here).
    const auto m = t.server->memory_stats();
    EXPECT_LE(m.cache_bytes + m.factor_bytes, m.limit) << "beta " << 0.01 * k;
  }
  {
    const auto m = t.server->memory_stats();
    std::printf("memory budget: cache %zu MiB, factorizations %zu MiB (%zu pinned), %llu evicted\n",
                m.cache_bytes / kMiB, m.factor_bytes / kMiB, m.factor_pinned_bytes / kMiB,
                static_cast<unsigned long long>(m.factor_evictions));
    EXPECT_GE(m.factor_evictions, 40u);
  }
  std::printf("memory budget: RSS before open %zu MiB, after open %zu MiB, peak over 60 betas %zu MiB\n",
              rss_before / kMiB, rss_open / kMiB, peak / kMiB);
  if (kMeasureRss) {
    EXPECT_LE(peak, rss_open + o.cache_bytes + kSlack)
        << "peak RSS " << peak / kMiB << " MiB, after open " << rss_open / kMiB << " MiB";
  }

  // β = 0.01 was evicted long ago: rebuilt on demand, the same bits.
  ASSERT_TRUE(t.set_beta(s.name(), 0.01, &s).ok());
  EXPECT_EQ(positions_at(t, s.name(), seq++), first);

  // Deleted: what is left is what the cache keeps for a later session on this mesh, within
  // the budget.
  ASSERT_TRUE(t.delete_session(s.name()).ok());
  const std::size_t rss_after = rss_bytes();
  std::printf("memory budget: RSS after delete %zu MiB\n", rss_after / kMiB);
  if (kMeasureRss) {
    EXPECT_LE(rss_after, rss_before + o.cache_bytes + kSlack)
        << "after delete " << rss_after / kMiB << " MiB, before open " << rss_before / kMiB;
  }
}

}  // namespace
