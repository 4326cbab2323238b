// OrderingStore (server/service/session/ordering_store.h) over a real SQLite state: the
// orderings a mesh computed are kept by its hash, a fresh copy of the mesh takes them instead
// of calling METIS, and what does not fit (garbage, another mesh) is ignored and rewritten.
#include "service_fixture.h"

#include "engine/io/mesh_io.h"
#include "service/infra/cache.h"
#include "service/session/ordering_store.h"
#include "stored_session.pb.h"

#include <numeric>

using namespace hdeform;
using namespace hdeform::service;
using hdeform::testing::TempDir;

namespace {

std::shared_ptr<MeshRef> cactus_ref() {
  auto r = std::make_shared<MeshRef>();
  TriMesh mesh = read_mesh(std::string(HDEFORM_TEST_DATA) + "/botsch-sorkine/cactus.off").mesh;
  r->hash = mesh_hash(mesh);
  r->prepared = PreparedMesh::create(std::move(mesh), PrepareOrder::on_first_use);  // as load_mesh
  return r;
}

state::StoredOrderings stored(StateBackend& backend, const std::string& hash) {
  state::StoredOrderings out;
  const auto bytes = backend.get_derived(hash);
  EXPECT_TRUE(bytes.has_value());
  if (bytes) {
    EXPECT_TRUE(out.ParseFromString(*bytes));
  }
  return out;
}

TEST(OrderingStore, ComputedOrderingsAreKeptAndAFreshCopyTakesThem) {
  TempDir dir;
  auto backend = open_sqlite_state(dir.path / "state");
  OrderingStore orderings(*backend);
  const auto computed = cactus_ref();
  orderings.keep({computed});
  EXPECT_EQ(backend->get_derived(computed->hash), std::nullopt) << "nothing computed yet";

  const std::vector<int> order = computed->prepared->order();
  orderings.keep({computed});
  state::StoredOrderings s = stored(*backend, computed->hash);
  EXPECT_EQ(s.mesh_hash(), computed->hash);
  EXPECT_EQ(s.vertices(), computed->prepared->n());
  EXPECT_EQ(std::vector<int>(s.order().begin(), s.order().end()), order);
  EXPECT_EQ(s.wide_order_size(), 0);

  const std::vector<int> wide = computed->prepared->wide_order();
  orderings.keep({computed});  // the β > 0 one, once it is there
  s = stored(*backend, computed->hash);
  EXPECT_EQ(std::vector<int>(s.wide_order().begin(), s.wide_order().end()), wide);

  // A restart: a new store object and a fresh copy of the mesh take both, no METIS call.
  OrderingStore after(*backend);
  const auto fresh = cactus_ref();
  after.prime(*fresh);
  ASSERT_TRUE(fresh->prepared->has_order());
  ASSERT_TRUE(fresh->prepared->has_wide_order());
  double ms = -1;
  EXPECT_EQ(fresh->prepared->order(&ms), order);
  EXPECT_EQ(ms, 0);
  EXPECT_EQ(fresh->prepared->wide_order(), wide);
}

TEST(OrderingStore, TheStoredOrderIsWhatIsTaken) {
  // A valid permutation METIS would never produce: taken as it is, so the store is read.
  TempDir dir;
  auto backend = open_sqlite_state(dir.path / "state");
  const auto mesh = cactus_ref();
  state::StoredOrderings s;
  s.set_mesh_hash(mesh->hash);
  s.set_vertices(mesh->prepared->n());
  std::vector<int> reversed(static_cast<std::size_t>(mesh->prepared->n()));
  std::iota(reversed.rbegin(), reversed.rend(), 0);
  s.mutable_order()->Add(reversed.begin(), reversed.end());
  backend->put_derived(mesh->hash, s.SerializeAsString());
  OrderingStore(*backend).prime(*mesh);
  EXPECT_EQ(mesh->prepared->order(), reversed);
  EXPECT_FALSE(mesh->prepared->has_wide_order()) << "not stored: computed when needed";
}

TEST(OrderingStore, WhatDoesNotFitIsIgnoredAndWrittenAgain) {
  TempDir dir;
  auto backend = open_sqlite_state(dir.path / "state");
  const auto mesh = cactus_ref();
  auto refused = [&](const std::string& bytes, const char* what) {
    SCOPED_TRACE(what);
    backend->put_derived(mesh->hash, bytes);
    const auto copy = cactus_ref();
    OrderingStore(*backend).prime(*copy);  // never throws
    EXPECT_FALSE(copy->prepared->has_order());
    EXPECT_FALSE(copy->prepared->has_wide_order());
  };
  refused("not a protobuf \xff\xff\xff", "garbage");
  state::StoredOrderings s;
  s.set_mesh_hash(std::string(64, 'e'));
  s.set_vertices(mesh->prepared->n());
  s.mutable_order()->Add(0);
  refused(s.SerializeAsString(), "another mesh's hash");
  s.set_mesh_hash(mesh->hash);
  s.set_vertices(mesh->prepared->n() + 1);
  refused(s.SerializeAsString(), "another vertex count");
  s.set_vertices(mesh->prepared->n());
  refused(s.SerializeAsString(), "not a permutation of the vertices");

  // The next keep writes a good one over it.
  OrderingStore orderings(*backend);
  const auto computed = cactus_ref();
  orderings.prime(*computed);
  computed->prepared->order();
  orderings.keep({computed});
  EXPECT_EQ(stored(*backend, computed->hash).order_size(), computed->prepared->n());
}

}  // namespace
