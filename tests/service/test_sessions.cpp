// Sessions over loopback: library, upload, constraints, β, meshes, sweeps.
#include "editors_fixture.h"
#include "service_fixture.h"

#include <cstring>
#include <set>
#include <sstream>

using namespace hdeform::testing;

TEST(ServiceSessions, ListsTheLibrary) {
  TestServer t;
  grpc::ClientContext ctx;
  pb::ListMeshesResponse resp;
  ASSERT_TRUE(t.stub->ListMeshes(&ctx, {}, &resp).ok());
  std::set<std::string> names;
  bool cactus_bench = false;
  for (const auto& m : resp.meshes()) {
    names.insert(m.name());
    if (m.name() == "cactus") cactus_bench = m.has_benchmark();
  }
  EXPECT_TRUE(names.count("cactus"));
  EXPECT_TRUE(names.count("knight"));
  EXPECT_TRUE(cactus_bench);
}

TEST(ServiceSessions, CreateGetListDelete) {
  TestServer t;
  const pb::Session a = t.library_session("cactus");
  const pb::Session b = t.library_session("cactus");
  EXPECT_EQ(a.vertex_count(), 5261);
  EXPECT_EQ(a.triangle_count(), 10518);
  EXPECT_EQ(a.mesh_name(), "cactus");
  EXPECT_FALSE(a.constrained());
  EXPECT_NE(a.name(), b.name());
  EXPECT_EQ(a.mesh_hash(), b.mesh_hash());  // content hash: one shared PreparedMesh
  EXPECT_EQ(a.mesh_hash().size(), 64u);  // SHA-256

  pb::ListSessionsResponse list;
  ASSERT_TRUE(t.list_sessions(&list).ok());
  EXPECT_EQ(list.sessions_size(), 2);
  pb::Session got;
  ASSERT_TRUE(t.get_session(a.name(), &got).ok());
  EXPECT_EQ(got.name(), a.name());
  ASSERT_TRUE(t.delete_session(a.name()).ok());
  EXPECT_EQ(t.get_session(a.name(), &got).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(ServiceSessions, UploadLargerThanFourMiB) {
  TestServer t;
  const std::string off = grid_off(220);
  ASSERT_GT(off.size(), 4u << 20);
  pb::Session s;
  auto st = t.upload(off, "grid.off", &s, 1u << 20, /*declare_size=*/true);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(s.vertex_count(), 220 * 220);
  EXPECT_EQ(s.triangle_count(), 2 * 219 * 219);
  EXPECT_EQ(s.mesh_name(), "grid.off");

  // The same bytes again (other chunking): the same mesh, shared.
  pb::Session s2;
  st = t.upload(off, "grid.off", &s2, 3u << 20);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(s2.mesh_hash(), s.mesh_hash());

  // The rest mesh comes back in ≤ 1 MiB chunks.
  std::string glb;
  std::vector<std::size_t> sizes;
  ASSERT_TRUE(t.get_mesh(s.name(), true, pb::MESH_FORMAT_GLB, &glb, &sizes).ok());
  ASSERT_GT(sizes.size(), 1u);
  for (auto n : sizes) EXPECT_LE(n, 1u << 20);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
}

TEST(ServiceSessions, ConstraintsBetaAndFrames) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  pb::Session c;
  auto st = t.set_constraints(s.name(), cactus_constraints(), &c);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(c.constrained());
  EXPECT_TRUE(c.has_constraints());
  ASSERT_EQ(c.constraints().handles_size(), 1);
  EXPECT_GT(c.constraints().fixed().ids_size(), 0);
  EXPECT_GT(c.constraints().handles(0).ids_size(), 0);
  ASSERT_EQ(c.transforms_size(), 1);
  ASSERT_EQ(c.pivots_size(), 1);
  EXPECT_GT(c.version(), s.version());

  pb::Frame f0;
  st = t.update(s.name(), 7, {cactus_transform()}, &f0, /*energies=*/true);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(f0.sequence(), 7);
  EXPECT_EQ(f0.session(), s.name());
  EXPECT_EQ(f0.positions().size(), 5261u * 3 * sizeof(float));
  EXPECT_EQ(f0.normals().size(), 5261u * 3 * sizeof(float));
  EXPECT_EQ(f0.energies().size(), 10518u * sizeof(float));
  EXPECT_GT(f0.measures().e(), 0);

  pb::Session b;
  st = t.set_beta(s.name(), 0.5, &b);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(b.beta().value(), 0.5);
  EXPECT_GT(b.version(), f0.version());
  ASSERT_EQ(b.transforms_size(), 1);  // β keeps the transforms

  pb::Frame f1;
  st = t.update(s.name(), 8, {cactus_transform()}, &f1);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(f1.beta().value(), 0.5);
  EXPECT_NE(f1.positions(), f0.positions());  // β changes the deformation
  EXPECT_TRUE(f1.energies().empty());

  // The deformed mesh as a file matches the frame (float32 of the same positions).
  std::string glb;
  ASSERT_TRUE(t.get_mesh(s.name(), false, pb::MESH_FORMAT_GLB, &glb).ok());
  EXPECT_NE(glb.find(f1.positions()), std::string::npos);
  std::string off;
  ASSERT_TRUE(t.get_mesh(s.name(), false, pb::MESH_FORMAT_OFF, &off).ok());
  EXPECT_EQ(off.substr(0, 3), "OFF");

  // SetConstraints again resets the transforms to identity.
  st = t.set_constraints(s.name(), cactus_constraints(), &c);
  ASSERT_TRUE(st.ok());
  ASSERT_EQ(c.transforms_size(), 1);
  EXPECT_EQ(c.transforms(0).translation().x(), 0);
  EXPECT_EQ(c.transforms(0).rotation().w(), 1);
}

TEST(ServiceSessions, Sweep) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  pb::Session c;
  ASSERT_TRUE(t.set_constraints(s.name(), cactus_constraints(), &c).ok());
  grpc::ClientContext ctx;
  pb::SweepRequest req;
  req.set_name(s.name());
  req.add_betas(0);
  req.add_betas(0.5);
  *req.add_transforms() = cactus_transform();
  pb::SweepResponse resp;
  auto st = t.stub->Sweep(&ctx, req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(resp.rows_size(), 2);
  EXPECT_EQ(resp.rows(1).beta(), 0.5);
  EXPECT_GT(resp.rows(0).measures().e(), 0);
  EXPECT_NE(resp.rows(0).measures().e(), resp.rows(1).measures().e());
}

// A quad mesh (what Blender exports) is solved as triangles and comes back, deformed, as the
// user's own quads, in OBJ, OFF and PLY (GLB stays triangles).
TEST(Sessions, QuadUploadsComeBackAsQuads) {
  TestServer t;
  std::string obj;
  const int n = 6;  // a 6 × 6 grid of quads
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      obj += "v ";
      obj += std::to_string(i);
      obj += ' ';
      obj += std::to_string(j);
      obj += " 0\n";
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1;
      obj += "f ";
      for (int c : {a, a + 1, a + n + 2, a + n + 1}) {
        obj += std::to_string(c);
        obj += ' ';
      }
      obj += '\n';
    }
  pb::Session s;
  ASSERT_TRUE(t.upload(obj, "quads.obj", &s).ok());
  EXPECT_EQ(s.triangle_count(), 2 * n * n);
  pb::Constraints c;
  *c.mutable_fixed()->add_selectors() = box(-0.5, -0.5, 0.5, n + 0.5);
  *c.add_handles()->add_selectors() = box(n - 0.5, -0.5, n + 0.5, n + 0.5);
  pb::Session constrained;
  ASSERT_TRUE(t.set_constraints(s.name(), c, &constrained).ok());
  pb::UpdateHandlesRequest u;
  u.set_name(s.name());
  *u.add_transforms() = translation(0, 0, 1);
  pb::Frame f;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, u, &f).ok());
  }
  const std::string out = t.deformed(s.name(), pb::MESH_FORMAT_OBJ);
  std::size_t quads = 0, others = 0;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("f ", 0) != 0) continue;
    std::istringstream ids(line.substr(2));
    int k = 0;
    for (std::string id; ids >> id;) ++k;
    (k == 4 ? quads : others) += 1;
  }
  EXPECT_EQ(quads, static_cast<std::size_t>(n * n));
  EXPECT_EQ(others, 0u);
  EXPECT_NE(out.find("\nf 1 2 9 8"), std::string::npos);  // the first face as given
  const std::string off = t.deformed(s.name(), pb::MESH_FORMAT_OFF);
  EXPECT_NE(off.find("\n49 36 0\n"), std::string::npos);  // 49 vertices, 36 faces
  EXPECT_NE(off.find("\n4 0 1 8 7\n"), std::string::npos);
}
