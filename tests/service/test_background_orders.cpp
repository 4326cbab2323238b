// BackgroundOrders (server/service/session/background_orders.h): a new mesh's β = 0 and
// β > 0 orders computed on an idle thread and adopted by the mesh, within its bounds (size
// threshold, queue, budget), and dropped when nobody needs them; and a real server that
// keeps both in its state before any SetConstraints or β > 0 change.
#include "service_fixture.h"

#include "engine/deform/factor_budget.h"
#include "engine/io/mesh_io.h"
#include "engine/solve/vertex_ordering.h"
#include "service/infra/cache.h"
#include "service/session/background_orders.h"
#include "stored_session.pb.h"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <sched.h>
#include <thread>

using namespace hdeform;
using namespace hdeform::service;
using hdeform::testing::TempDir;
namespace pb = hdeform::v1;

namespace {

std::shared_ptr<const MeshRef> ref_of(TriMesh mesh) {
  auto r = std::make_shared<MeshRef>();
  r->hash = mesh_hash(mesh);
  r->prepared = PreparedMesh::create(std::move(mesh), PrepareOrder::on_first_use);  // as load_mesh
  return r;
}

std::shared_ptr<const MeshRef> cactus() {
  return ref_of(read_mesh(std::string(HDEFORM_TEST_DATA) + "/botsch-sorkine/cactus.off").mesh);
}

std::shared_ptr<FactorBudget> roomy() { return std::make_shared<FactorBudget>(1ull << 40); }

// Holds the worker inside its first order until opened: the budget's other_bytes() is read
// by charge_if_room at the start of each mesh's orders (busy is set by then). No timing.
struct Gate {
  std::mutex mutex;
  std::condition_variable cv;
  bool open = false;
  void release() {
    {
      std::lock_guard lock(mutex);
      open = true;
    }
    cv.notify_all();
  }
  std::shared_ptr<FactorBudget> budget() {
    return std::make_shared<FactorBudget>(1ull << 40, [this]() -> std::size_t {
      std::unique_lock lock(mutex);
      cv.wait(lock, [&] { return open; });
      return 0;
    });
  }
};

// Waits up to a minute for `done` (the worker runs at SCHED_IDLE: slow on a busy host).
bool eventually(const std::function<bool()>& done) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::minutes(1);
  while (!done()) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

// At the default CPU priority: a test must not wait for idle cores (ctest runs two
// suites at once); the lowest priority has its own test.
BackgroundOrders::Options from(std::size_t vertices, std::size_t max_queued = 16) {
  return {.from_vertices = vertices, .max_queued = max_queued, .lowest_priority = false};
}

// The file's bytes; empty when it is not there (yet).
std::string bytes_of(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream out;
  if (in) out << in.rdbuf();
  return out.str();
}

// A server keeping its state in dir (SQLite), with background orders from `from` vertices.
ServerOptions durable(const TempDir& dir, std::size_t from) {
  ServerOptions options;
  options.state_dir = (dir.path / "state").string();
  options.background_order_from = from;
  return options;
}

// Where that server keeps a mesh's orders (sqlite_state: DIR/derived/HASH.order).
std::filesystem::path orders_file(const TempDir& dir, const std::string& mesh_hash) {
  return dir.path / "state" / "derived" / (mesh_hash + ".order");
}

// A session on the cactus with constraints (β = 0), stored by a server that has stopped.
void stored_constrained_cactus(const ServerOptions& options, pb::Session* created) {
  hdeform::testing::TestServer a(options);
  ASSERT_TRUE(a.create_library("cactus", created).ok());
  pb::Session constrained;
  ASSERT_TRUE(a.set_constraints(created->name(), hdeform::testing::cactus_constraints(),
                                &constrained).ok());
}

}  // namespace

TEST(BackgroundOrders, AQueuedMeshGetsTheOrdersItsFirstCallsWouldCompute) {
  BackgroundOrders orders(from(1), roomy());
  const auto mesh = cactus();
  orders.enqueue(mesh);
  ASSERT_TRUE(eventually([&] { return orders.stats().computed == 2; }));
  const PreparedMesh& pm = *mesh->prepared;
  ASSERT_TRUE(pm.has_order());
  ASSERT_TRUE(pm.has_wide_order());
  double ms = -1;
  EXPECT_EQ(pm.order(&ms), nested_dissection(pm.L()));
  EXPECT_EQ(ms, 0) << "SetConstraints takes it without a METIS call";
  ms = -1;
  EXPECT_EQ(pm.wide_order(&ms), nested_dissection(pm.L(), pm.Reg()));
  EXPECT_EQ(ms, 0) << "a β > 0 takes it without a METIS call";
  const auto s = orders.stats();
  EXPECT_EQ(s.superseded + s.closed + s.no_room + s.queue_full + s.failed, 0u);
}

// Checked before any order runs: on two busy cores (ctest -j2) a SCHED_IDLE order may wait
// a long time for a core, which is the point of it.
TEST(BackgroundOrders, TheWorkerRunsAtTheLowestPriority) {
  Gate gate;
  BackgroundOrders::Options options = from(1);
  options.lowest_priority = true;
  BackgroundOrders orders(options, gate.budget());
  const auto mesh = cactus();
  orders.enqueue(mesh);
  ASSERT_TRUE(eventually([&] { return orders.stats().busy; }));
  EXPECT_TRUE(orders.stats().idle_priority) << "SCHED_IDLE needs no privilege on Linux";
  EXPECT_EQ(sched_getscheduler(0), SCHED_OTHER) << "the caller's own policy is untouched";
  const auto waiting = cactus();
  orders.enqueue(waiting);
  ASSERT_EQ(orders.stats().queued, 1u);
  orders.stop();
  gate.release();  // the stop comes first: the worker returns without ordering
  orders.join();
  EXPECT_EQ(orders.stats().computed, 0u);
  EXPECT_FALSE(mesh->prepared->has_order());
}

TEST(BackgroundOrders, SmallMeshesOrderedMeshesAndAZeroThresholdAreNotQueued) {
  const auto mesh = cactus();
  const auto n = static_cast<std::size_t>(mesh->prepared->n());
  {
    BackgroundOrders orders(from(n + 1), roomy());
    orders.enqueue(mesh);
    EXPECT_EQ(orders.stats().queued, 0u);
  }
  {
    BackgroundOrders orders(from(0), roomy());
    orders.enqueue(mesh);
    EXPECT_EQ(orders.stats().queued, 0u);
  }
  EXPECT_FALSE(mesh->prepared->has_order());
  EXPECT_FALSE(mesh->prepared->has_wide_order());
  mesh->prepared->order();       // a SetConstraints came first
  mesh->prepared->wide_order();  // and a β > 0
  BackgroundOrders orders(from(n), roomy());
  orders.enqueue(mesh);
  orders.enqueue(nullptr);
  EXPECT_EQ(orders.stats().queued, 0u);
  orders.stop();
  EXPECT_EQ(orders.stats().computed, 0u);
}

TEST(BackgroundOrders, AMeshEveryoneLetGoOfIsNotOrderedAndOneMeshIsQueuedOnce) {
  Gate gate;
  BackgroundOrders orders(from(1), gate.budget());
  const auto busy = cactus();
  orders.enqueue(busy);
  ASSERT_TRUE(eventually([&] { return orders.stats().busy; }));
  auto closed = cactus();
  const auto kept = cactus();
  const PreparedMesh* closed_mesh = closed->prepared.get();
  const auto closed_prepared = closed->prepared;  // the mesh outlives its last session here
  orders.enqueue(closed);
  orders.enqueue(kept);
  orders.enqueue(kept);  // a second session on the same mesh
  EXPECT_EQ(orders.stats().queued, 2u);
  closed.reset();
  gate.release();
  ASSERT_TRUE(eventually([&] { return orders.stats().computed == 4; }));
  const auto s = orders.stats();
  EXPECT_EQ(s.closed, 1u);
  EXPECT_EQ(s.queued, 0u);
  EXPECT_FALSE(closed_mesh->has_order());
  EXPECT_FALSE(closed_mesh->has_wide_order());
  EXPECT_TRUE(kept->prepared->has_wide_order());
  EXPECT_TRUE(busy->prepared->has_wide_order());
}

TEST(BackgroundOrders, AFullQueueDropsItsOldest) {
  Gate gate;
  BackgroundOrders orders(from(1, /*max_queued=*/2), gate.budget());
  std::vector<std::shared_ptr<const MeshRef>> meshes;
  for (int i = 0; i < 4; ++i) meshes.push_back(cactus());
  const auto busy = cactus();
  orders.enqueue(busy);
  ASSERT_TRUE(eventually([&] { return orders.stats().busy; }));
  for (const auto& m : meshes) orders.enqueue(m);
  EXPECT_EQ(orders.stats().queue_full, 2u);
  EXPECT_EQ(orders.stats().queued, 2u);
  gate.release();
  ASSERT_TRUE(eventually([&] { return orders.stats().computed == 6; }));
  EXPECT_FALSE(meshes[0]->prepared->has_wide_order());
  EXPECT_FALSE(meshes[1]->prepared->has_wide_order());
  EXPECT_TRUE(meshes[2]->prepared->has_wide_order());
  EXPECT_TRUE(meshes[3]->prepared->has_wide_order());
}

TEST(BackgroundOrders, ABetaThatComesFirstSupersedesIt) {
  Gate gate;
  BackgroundOrders orders(from(1), gate.budget());
  const auto busy = cactus();
  orders.enqueue(busy);
  ASSERT_TRUE(eventually([&] { return orders.stats().busy; }));
  const auto mesh = cactus();
  orders.enqueue(mesh);
  const std::vector<int> own = mesh->prepared->wide_order();  // the β > 0 change's METIS
  gate.release();
  ASSERT_TRUE(eventually([&] {
    const auto s = orders.stats();
    return s.computed == 3 && s.superseded == 1;  // the first mesh's two, this one's β = 0
  }));
  EXPECT_EQ(mesh->prepared->wide_order(), own);
}

TEST(BackgroundOrders, NoRoomInTheBudgetSkipsTheOrderAndEvictsNothing) {
  struct Cached : FactorBudget::Item {};
  struct Owner : FactorBudget::Owner {
    mutable int evicted = 0;
    void evict(const FactorBudget::Item&) const override { ++evicted; }
  };
  const auto mesh = cactus();
  const std::size_t need = BackgroundOrders::working_bytes(mesh->prepared->n());
  ASSERT_GT(need, 0u);
  // A cached system leaves one byte too few for the order's working memory.
  const std::size_t cached_bytes = 1000;
  auto budget = std::make_shared<FactorBudget>(cached_bytes + need - 1);
  const auto owner = std::make_shared<const Owner>();
  const auto cached = std::make_shared<const Cached>();
  budget->charge(owner, cached, cached_bytes, /*pinned=*/false);
  {
    BackgroundOrders orders(from(1), budget);
    orders.enqueue(mesh);
    ASSERT_TRUE(eventually([&] { return orders.stats().no_room == 1; }));
  }
  EXPECT_FALSE(mesh->prepared->has_order());
  EXPECT_FALSE(mesh->prepared->has_wide_order());
  EXPECT_EQ(owner->evicted, 0);
  EXPECT_EQ(budget->stats().evictions, 0u);
  EXPECT_EQ(budget->stats().charged, cached_bytes) << "nothing left charged";

  // With the byte back it runs, charged while it runs, and releases its charge after.
  auto enough = std::make_shared<FactorBudget>(cached_bytes + need);
  enough->charge(owner, cached, cached_bytes, /*pinned=*/false);
  BackgroundOrders orders(from(1), enough);
  orders.enqueue(mesh);
  ASSERT_TRUE(eventually([&] {  // the charge ends when the mesh's orders do (not busy)
    const auto s = orders.stats();
    return s.computed == 2 && !s.busy;
  }));
  EXPECT_EQ(enough->stats().charged, cached_bytes);
  EXPECT_EQ(owner->evicted, 0);
}

// stop() returns at once, the worker still held (a server stores its sessions meanwhile:
// SessionStore::shutdown); the order in progress ends, none starts after the stop (not even
// the same mesh's next), and join() waits for it.
TEST(BackgroundOrders, StopDropsTheQueueAndStartsNoOrderJoinWaits) {
  Gate gate;
  const auto busy = cactus();
  const auto queued = cactus();
  BackgroundOrders orders(from(1), gate.budget());
  orders.enqueue(busy);
  ASSERT_TRUE(eventually([&] { return orders.stats().busy; }));
  orders.enqueue(queued);
  orders.stop();  // would never return here if it waited for the held worker
  EXPECT_EQ(orders.stats().queued, 0u);
  EXPECT_TRUE(orders.stats().busy);
  gate.release();
  orders.join();
  const auto s = orders.stats();
  EXPECT_FALSE(s.busy);
  EXPECT_EQ(s.computed, 0u);
  EXPECT_FALSE(busy->prepared->has_order());
  EXPECT_FALSE(busy->prepared->has_wide_order());
  EXPECT_FALSE(queued->prepared->has_order());
  EXPECT_FALSE(queued->prepared->has_wide_order());
  orders.enqueue(queued);  // after stop: ignored
  EXPECT_EQ(orders.stats().queued, 0u);
}

// End to end: a server with a state folder keeps a new session's orders in its state
// (DIR/derived/HASH.order) although no client set constraints or β > 0, so a restart,
// another replica or a later session on the mesh skips those METIS calls.
TEST(BackgroundOrders, AServerStoresANewMeshsOrdersBeforeAnyChange) {
  TempDir dir;
  ServerOptions options = durable(dir, 1);
  hdeform::testing::TestServer t(options);
  pb::Session created;
  ASSERT_TRUE(t.create_library("cactus", &created).ok());
  const auto file = orders_file(dir, created.mesh_hash());
  state::StoredOrderings stored;
  ASSERT_TRUE(eventually([&] {
    return stored.ParseFromString(bytes_of(file)) &&
           stored.wide_order_size() > 0;
  })) << "no β > 0 order in " << file;
  ASSERT_GT(stored.order_size(), 0) << "the β = 0 order is computed first";
  const auto mesh = cactus();
  ASSERT_EQ(mesh->hash, created.mesh_hash()) << "the library's cactus is the file's";
  const PreparedMesh& pm = *mesh->prepared;
  EXPECT_EQ(stored.vertices(), pm.n());
  EXPECT_EQ(std::vector<int>(stored.order().begin(), stored.order().end()),
            nested_dissection(validate_mesh(pm.mesh()).edges));
  EXPECT_EQ(std::vector<int>(stored.wide_order().begin(), stored.wide_order().end()),
            nested_dissection(pm.L(), pm.Reg()));
}

// A session restored after a restart queues its mesh too: the β > 0 order its first server
// never computed (the session stayed at β = 0) is computed by the next and kept.
TEST(BackgroundOrders, ARestoredSessionsMeshGetsTheOrderItLacks) {
  TempDir dir;
  ServerOptions options = durable(dir, 0);
  pb::Session created;
  ASSERT_NO_FATAL_FAILURE(stored_constrained_cactus(options, &created));
  const auto file = orders_file(dir, created.mesh_hash());
  state::StoredOrderings stored;
  ASSERT_TRUE(stored.ParseFromString(bytes_of(file)));
  ASSERT_GT(stored.order_size(), 0) << "SetConstraints computed the β = 0 order";
  ASSERT_EQ(stored.wide_order_size(), 0) << "no β > 0 yet";

  options.background_order_from = 1;
  hdeform::testing::TestServer b(options);
  grpc::ClientContext ctx;
  pb::GetSessionRequest get;
  get.set_name(created.name());
  pb::Session restored;
  ASSERT_TRUE(b.stub->GetSession(&ctx, get, &restored).ok());
  ASSERT_TRUE(eventually([&] {
    return stored.ParseFromString(bytes_of(file)) && stored.wide_order_size() > 0;
  })) << "no β > 0 order in " << file;
  const auto mesh = cactus();
  EXPECT_EQ(std::vector<int>(stored.wide_order().begin(), stored.wide_order().end()),
            nested_dissection(mesh->prepared->L(), mesh->prepared->Reg()));
  // Counted after the mesh adopts the order, which the flusher may have written already.
  ASSERT_TRUE(eventually([&] { return !b.server->background_orders().busy; }));
  const auto s = b.server->background_orders();
  EXPECT_EQ(s.computed, 1u) << "the β = 0 order came from the store";
  EXPECT_EQ(s.superseded, 1u);
}

// A restore that factors at once (its session has constraints) and finds no stored β = 0
// order has its mesh ordered beside the operators (PrepareOrder::with_operators); one that
// finds it takes it, and no METIS runs in the open.
TEST(BackgroundOrders, ARestoreWithoutItsStoredOrderOrdersBesideTheOperators) {
  TempDir dir;
  ServerOptions options = durable(dir, 0);
  pb::Session created;
  ASSERT_NO_FATAL_FAILURE(stored_constrained_cactus(options, &created));
  const auto file = orders_file(dir, created.mesh_hash());
  ASSERT_TRUE(std::filesystem::exists(file));
  const std::string kept = bytes_of(file);
  auto restore = [&](bool with_orders) {
    if (with_orders) {
      std::ofstream(file, std::ios::binary) << kept;
    } else {
      std::filesystem::remove(file);
    }
    hdeform::testing::TestServer b(options);
    grpc::ClientContext ctx;
    pb::GetSessionRequest get;
    get.set_name(created.name());
    pb::Session restored;
    EXPECT_TRUE(b.stub->GetSession(&ctx, get, &restored).ok());
    const auto pm = b.server->prepared_mesh(created.mesh_hash());
    EXPECT_TRUE(pm && pm->has_order());
    return pm ? pm->build_timings() : PreparedMesh::BuildTimings{};
  };
  const auto cold = restore(false);
  EXPECT_GT(cold.order_ms, 0.0) << "ordered in the open, beside the operators";
  EXPECT_GT(cold.beside_ms, 0.0);
  const auto warm = restore(true);
  EXPECT_EQ(warm.order_ms, 0.0) << "the stored order was taken";
  EXPECT_EQ(warm.beside_ms, 0.0);
}

// --order-on-open (the in-process CLI's setting): a CreateSession's mesh has its β = 0 order
// when the call answers, computed beside its operators; without it the order waits for its
// first use (no background orders here).
TEST(BackgroundOrders, OrderOnOpenOrdersTheNewMeshBesideItsOperators) {
  for (bool on : {false, true}) {
    SCOPED_TRACE(on ? "--order-on-open" : "default");
    ServerOptions options;
    options.background_order_from = 0;
    options.order_on_open = on;
    hdeform::testing::TestServer t(options);
    pb::Session created;
    ASSERT_TRUE(t.create_library("cactus", &created).ok());
    const auto pm = t.server->prepared_mesh(created.mesh_hash());
    ASSERT_TRUE(pm);
    EXPECT_EQ(pm->has_order(), on);
    EXPECT_EQ(pm->build_timings().order_ms > 0, on);
  }
}

TEST(BackgroundOrders, AServerWithTheThresholdAtZeroOrdersNothingInTheBackground) {
  TempDir dir;
  ServerOptions options = durable(dir, 0);
  pb::Session created;
  {
    hdeform::testing::TestServer t(options);
    ASSERT_TRUE(t.create_library("cactus", &created).ok());
  }  // a clean stop flushes what was computed
  const auto file = orders_file(dir, created.mesh_hash());
  state::StoredOrderings stored;
  if (std::filesystem::exists(file)) {
    ASSERT_TRUE(stored.ParseFromString(bytes_of(file)));
  }
  EXPECT_EQ(stored.order_size(), 0);
  EXPECT_EQ(stored.wide_order_size(), 0);
}
