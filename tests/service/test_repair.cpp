// Opt-in repair of an upload (CreateSessionHeader.repair): a mesh validation refuses opens
// repaired, the answer says what changed and maps base-GLB ids back to the upload's, and an
// export, import or restore from durable state repeats the repair. Real servers on loopback.
#include "service_fixture.h"

#include <filesystem>
#include <sstream>

using namespace hdeform::testing;
using grpc::StatusCode;

namespace {

// Two triangles touching at vertex 1 only: a non-manifold (bowtie) vertex.
const char* kBowtie =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\n"
    "f 1 2 3\nf 1 4 5\n";

// A unit cube written as six separate quads (24 vertices): valid, but six loose faces.
std::string separate_face_cube() {
  const int quads[6][4][3] = {
      {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
      {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
      {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}}};
  std::string v, f;
  int next = 1;
  for (const auto& q : quads) {
    f += "f";
    for (const auto& p : q) {
      v += "v " + std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
      f += " " + std::to_string(next++);
    }
    f += "\n";
  }
  return v + f;
}

grpc::Status upload_repaired(TestServer& t, const std::string& bytes, const std::string& filename,
                             pb::Session* out, double tolerance = 0) {
  grpc::ClientContext ctx;
  auto writer = t.stub->CreateSession(&ctx, out);
  pb::CreateSessionRequest req;
  req.mutable_header()->set_filename(filename);
  req.mutable_header()->mutable_repair()->set_merge_tolerance(tolerance);
  bool ok = writer->Write(req);
  pb::CreateSessionRequest chunk;
  chunk.set_chunk(bytes);
  ok = ok && writer->Write(chunk);
  writer->WritesDone();
  return writer->Finish();
}

}  // namespace

TEST(Repair, ABowtieRefusedAsUploadedOpensRepairedWithTheMapBack) {
  TestServer t;
  pb::Session s;
  auto st = t.upload(kBowtie, "bowtie.obj", &s);
  ASSERT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("non-manifold"), std::string::npos) << st.error_message();

  st = upload_repaired(t, kBowtie, "bowtie.obj", &s);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(s.vertex_count(), 6);  // vertex 0 split in two
  EXPECT_EQ(s.repair().split_vertices(), 1);
  EXPECT_EQ(s.repair().added_vertices(), 1);
  ASSERT_EQ(s.repair().base_to_input_size(), 6);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(s.repair().base_to_input(i), i);
  EXPECT_EQ(s.repair().base_to_input(5), 0);  // the copy maps back to the upload's vertex 0
  ASSERT_GE(s.repair().lines_size(), 1);
  pb::Session again;
  ASSERT_TRUE(t.get_session(s.name(), &again).ok());
  EXPECT_FALSE(again.has_repair());  // the report is the creation's answer only
}

TEST(Repair, LooseFacesAreWeldedAndKeepTheUploadsIds) {
  TestServer t;
  pb::Session plain, repaired;
  ASSERT_TRUE(t.upload(separate_face_cube(), "cube.obj", &plain).ok());
  const auto st = upload_repaired(t, separate_face_cube(), "cube.obj", &repaired);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_NE(plain.mesh_hash(), repaired.mesh_hash());  // a closed cube, not six faces
  EXPECT_EQ(repaired.repair().merged_vertices(), 16);
  EXPECT_EQ(repaired.vertex_count(), 24);  // written back in the upload's own 24 ids
  EXPECT_EQ(repaired.repair().base_to_input_size(), 0);
  // The solve sees a closed cube: GetMesh's OBJ is the welded surface (as for a glTF
  // upload), 8 vertices and 12 triangles, while the base GLB keeps the upload's 24 ids.
  std::string obj;
  ASSERT_TRUE(t.get_mesh(repaired.name(), true, pb::MESH_FORMAT_OBJ, &obj).ok());
  std::istringstream in(obj);
  int vertices = 0, triangles = 0;
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string kind, w;
    words >> kind;
    int corners = 0;
    while (words >> w) ++corners;
    vertices += kind == "v";
    triangles += kind == "f" && corners == 3;
  }
  EXPECT_EQ(vertices, 8);
  EXPECT_EQ(triangles, 12);
}

TEST(Repair, BadRequestsAreRefusedNamingTheField) {
  TestServer t;
  pb::Session s;
  auto st = upload_repaired(t, kBowtie, "bowtie.obj", &s, 0.5);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("repair.merge_tolerance"), std::string::npos)
      << st.error_message();
  st = upload_repaired(t, kBowtie, "bowtie.obj", &s, -1e-3);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  grpc::ClientContext ctx;
  auto writer = t.stub->CreateSession(&ctx, &s);
  pb::CreateSessionRequest req;
  req.mutable_header()->set_library_mesh("cactus");
  req.mutable_header()->mutable_repair();
  writer->Write(req);
  writer->WritesDone();
  st = writer->Finish();
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("library meshes need none"), std::string::npos)
      << st.error_message();
  // Still serving.
  EXPECT_TRUE(upload_repaired(t, kBowtie, "bowtie.obj", &s).ok());
}

TEST(Repair, ExportImportAndARestartRepeatTheRepair) {
  TempDir dir;
  hdeform::service::ServerOptions o;
  o.state_dir = (dir.path / "state").string();
  pb::Session s;
  pb::Snapshot snap;
  {
    TestServer t(o);
    ASSERT_TRUE(upload_repaired(t, kBowtie, "bowtie.obj", &s).ok());
    ASSERT_TRUE(t.export_session(s.name(), &snap, true).ok());
    EXPECT_TRUE(snap.has_repair());
    pb::Session imported;
    const auto st = t.import_session(snap, &imported);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(imported.mesh_hash(), s.mesh_hash());
    EXPECT_EQ(imported.repair().split_vertices(), 1);
  }
  TestServer t(o);  // restores from the stored upload: refused unless repaired again
  pb::Session restored;
  const auto st = t.get_session(s.name(), &restored);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(restored.mesh_hash(), s.mesh_hash());
  EXPECT_EQ(restored.vertex_count(), 6);
}
