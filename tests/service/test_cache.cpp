// The shared LRU and the worker pool's strands, without gRPC.
#include "service/infra/cache.h"
#include "service/infra/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

using hdeform::service::Cache;
using hdeform::service::Strand;
using hdeform::service::WorkerPool;

namespace {
struct Blob {
  std::size_t bytes;
};
std::shared_ptr<const Blob> get(Cache& c, const std::string& key, std::size_t bytes, int* builds) {
  return c.get_or_create<Blob>(
      key,
      [&]() -> std::shared_ptr<const Blob> {
        ++*builds;
        return std::make_shared<const Blob>(Blob{bytes});
      },
      [](const Blob& b) { return b.bytes; });
}
}  // namespace

TEST(ServiceCache, EvictsLeastRecentlyUsedWithinBudget) {
  Cache cache(100);
  int builds = 0;
  get(cache, "a", 40, &builds);
  get(cache, "b", 40, &builds);
  get(cache, "a", 40, &builds);  // hit: a is now the most recent
  EXPECT_EQ(builds, 2);
  get(cache, "c", 40, &builds);  // over budget: b goes
  EXPECT_LE(cache.stats().bytes, 100u);
  EXPECT_EQ(cache.stats().evictions, 1u);
  get(cache, "a", 40, &builds);
  EXPECT_EQ(builds, 3);
  get(cache, "b", 40, &builds);  // rebuilt
  EXPECT_EQ(builds, 4);
}

TEST(ServiceCache, EvictedButLiveObjectsAreFoundAgain) {
  Cache cache(50);
  int builds = 0;
  auto held = get(cache, "a", 40, &builds);
  get(cache, "b", 40, &builds);  // evicts a from the LRU, but we still hold it
  auto again = get(cache, "a", 40, &builds);
  EXPECT_EQ(builds, 2);
  EXPECT_EQ(again.get(), held.get());
}

TEST(ServiceCache, ConcurrentCallersShareOneBuild) {
  Cache cache(1000);
  std::atomic<int> builds{0};
  std::vector<std::thread> threads;
  std::vector<const Blob*> seen(8);
  for (int i = 0; i < 8; ++i)
    threads.emplace_back([&, i] {
      auto p = cache.get_or_create<Blob>(
          "k",
          [&]() -> std::shared_ptr<const Blob> {
            ++builds;
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            return std::make_shared<const Blob>(Blob{10});
          },
          [](const Blob& b) { return b.bytes; });
      seen[i] = p.get();
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(builds.load(), 1);
  for (auto* p : seen) EXPECT_EQ(p, seen[0]);
}

TEST(ServiceWorkerPool, StrandRunsInOrderOneAtATime) {
  WorkerPool pool(2);
  auto strand = std::make_shared<Strand>(pool);
  std::mutex mutex;
  std::vector<int> order;
  std::atomic<int> running{0}, max_running{0};
  for (int i = 0; i < 200; ++i)
    strand->post([&, i] {
      const int r = ++running;
      max_running = std::max(max_running.load(), r);
      {
        std::lock_guard lock(mutex);
        order.push_back(i);
      }
      --running;
    });
  pool.stop();
  ASSERT_EQ(order.size(), 200u);
  for (int i = 0; i < 200; ++i) EXPECT_EQ(order[i], i);
  EXPECT_EQ(max_running.load(), 1);
}
