// Automatic β and local regularization through the service (Beta.automatic, Beta.local).
#include "service_fixture.h"

#include <limits>

using namespace hdeform::testing;

namespace {

// The topmost-z vertex of the session's mesh, as a selector (no vertex order needed).
pb::Selector top_vertex(const pb::Session& s) {
  pb::Selector sel;
  auto* h = sel.mutable_half_space();
  h->mutable_normal()->set_z(1);
  h->set_offset(s.bbox_max().z() - 1e-9);
  return sel;
}

// Cactus, fixed = cactus.sel label 0, one handle = the topmost vertex (thesis Figure 7.8,
// "Cactus Side"): the naive method leaves a protruding spike there.
pb::Constraints single_vertex_constraints(const pb::Session& s) {
  pb::Constraints c = cactus_constraints();
  c.clear_handles();
  *c.add_handles()->add_selectors() = top_vertex(s);
  return c;
}

pb::HandleTransform pull() { return translation(0.08, 0, 0); }

pb::Beta automatic(pb::BetaUnits units) {
  pb::Beta b;
  b.set_automatic(true);
  b.set_units(units);
  return b;
}

// β with one falloff entry around the top vertex (β = 0.3 within 0.03, area units).
pb::Beta local_around_top(const pb::Session& s, double beta = 0.3, double radius = 0.03) {
  pb::Beta b;
  auto* e = b.add_local();
  *e->mutable_region()->add_selectors() = top_vertex(s);
  e->set_beta(beta);
  e->set_falloff_radius(radius);
  return b;
}

struct SingleVertex {
  TestServer t;
  pb::Session s;
  pb::Frame naive;
  SingleVertex() {
    s = t.library_session("cactus");
    pb::Session c;
    auto st = t.set_constraints(s.name(), single_vertex_constraints(s), &c);
    EXPECT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(c.constraints().handles_size(), 1);
    EXPECT_EQ(c.constraints().handles(0).ids_size(), 1);
    st = t.update(s.name(), 1, {pull()}, &naive);
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
};

}  // namespace

TEST(ServiceBeta, AutomaticPicksTheRecommendedRangeForASingleVertexPull) {
  SingleVertex f;
  pb::Session after;
  auto st = f.t.set_beta(f.s.name(), automatic(pb::BETA_UNITS_RAW), &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(after.beta().automatic());
  EXPECT_EQ(after.beta().units(), pb::BETA_UNITS_RAW);
  EXPECT_GE(after.beta().value(), 0.1);
  EXPECT_LE(after.beta().value(), 0.25);

  pb::Frame reg;
  ASSERT_TRUE(f.t.update(f.s.name(), 2, {pull()}, &reg).ok());
  EXPECT_TRUE(reg.beta().automatic());
  EXPECT_EQ(reg.beta().value(), after.beta().value());
  EXPECT_LT(reg.measures().max_e_iso(), f.naive.measures().max_e_iso() / 10)
      << "naive " << f.naive.measures().max_e_iso() << " auto " << reg.measures().max_e_iso();
}

TEST(ServiceBeta, AutomaticOnTheCylinderBenchmarkPicksZero) {
  TestServer t;
  const pb::Session s = t.library_session("cylinder");
  pb::Session out;
  ASSERT_TRUE(t.set_constraints(s.name(), benchmark_constraints("cylinder"), &out).ok());
  pb::Frame f;
  ASSERT_TRUE(t.update(s.name(), 1, {benchmark_transform("cylinder")}, &f).ok());
  auto st = t.set_beta(s.name(), automatic(pb::BETA_UNITS_RAW), &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(out.beta().automatic());
  EXPECT_EQ(out.beta().value(), 0.0);
}

TEST(ServiceBeta, AutomaticNeedsConstraints) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  pb::Session out;
  auto st = t.set_beta(s.name(), automatic(pb::BETA_UNITS_AREA), &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
}

TEST(ServiceBeta, DeformStreamPicksAtTheMessagesTransforms) {
  SingleVertex f;
  grpc::ClientContext ctx;
  auto stream = f.t.stub->Deform(&ctx);
  pb::DeformRequest req = deform_request(f.s.name(), 7, pull());
  *req.mutable_beta() = automatic(pb::BETA_UNITS_RAW);
  ASSERT_TRUE(stream->Write(req));
  stream->WritesDone();
  pb::Frame frame;
  ASSERT_TRUE(stream->Read(&frame));
  while (stream->Read(&frame)) {
  }
  auto st = stream->Finish();
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(frame.sequence(), 7);
  EXPECT_TRUE(frame.beta().automatic());
  EXPECT_GE(frame.beta().value(), 0.1);
  EXPECT_LE(frame.beta().value(), 0.25);
  EXPECT_LT(frame.measures().max_e_iso(), f.naive.measures().max_e_iso() / 10);
}

TEST(ServiceBeta, LocalFalloffAroundTheHandleRemovesTheSpike) {
  SingleVertex f;
  pb::Session after;
  auto st = f.t.set_beta(f.s.name(), local_around_top(f.s), &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(after.beta().value(), 0.0);
  ASSERT_EQ(after.beta().local_size(), 1);
  EXPECT_EQ(after.beta().local(0).beta(), 0.3);

  pb::Frame reg;
  ASSERT_TRUE(f.t.update(f.s.name(), 2, {pull()}, &reg).ok());
  EXPECT_LT(reg.measures().max_e_iso(), f.naive.measures().max_e_iso() / 10)
      << "naive " << f.naive.measures().max_e_iso() << " local " << reg.measures().max_e_iso();

  // A region entry (radius 0) with β = 0 changes nothing: the naive result again.
  pb::Beta zero;
  auto* e = zero.add_local();
  *e->mutable_region()->add_selectors() = top_vertex(f.s);
  ASSERT_TRUE(f.t.set_beta(f.s.name(), zero, &after).ok());
  pb::Frame same;
  ASSERT_TRUE(f.t.update(f.s.name(), 3, {pull()}, &same).ok());
  EXPECT_NEAR(same.measures().max_e_iso(), f.naive.measures().max_e_iso(),
              1e-6 * f.naive.measures().max_e_iso());

  // Sweep applies the session's local entries at every β (value = that β).
  ASSERT_TRUE(f.t.set_beta(f.s.name(), local_around_top(f.s), &after).ok());
  grpc::ClientContext ctx;
  pb::SweepRequest sreq;
  sreq.set_name(f.s.name());
  sreq.add_betas(0.0);
  sreq.add_betas(0.3);
  pb::SweepResponse sweep;
  st = f.t.stub->Sweep(&ctx, sreq, &sweep);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(sweep.rows_size(), 2);
  EXPECT_NEAR(sweep.rows(0).measures().max_e_iso(), reg.measures().max_e_iso(),
              1e-9 * reg.measures().max_e_iso());
  // β = 0.3 everywhere (the local entry adds nothing): the uniform β = 0.3 result.
  pb::Session uniform;
  ASSERT_TRUE(f.t.set_beta(f.s.name(), 0.3, &uniform).ok());
  pb::Frame u;
  ASSERT_TRUE(f.t.update(f.s.name(), 4, {pull()}, &u).ok());
  EXPECT_NEAR(sweep.rows(1).measures().e(), u.measures().e(), 1e-7 * u.measures().e());
}

TEST(ServiceBeta, BadLocalEntriesAreInvalidArgument) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  struct Case {
    const char* what;
    pb::Beta beta;
    const char* message;
  };
  std::vector<Case> cases;
  {
    pb::Beta b = local_around_top(s, 1.0);
    cases.push_back({"beta 1", b, "local[0]: beta must satisfy"});
  }
  {
    pb::Beta b = local_around_top(s, -0.1);
    cases.push_back({"beta < 0", b, "local[0]: beta must satisfy"});
  }
  {
    pb::Beta b = local_around_top(s, 0.3, -1);
    cases.push_back({"negative radius", b, "falloff_radius"});
  }
  {
    pb::Beta b = local_around_top(s, 0.3, std::numeric_limits<double>::infinity());
    cases.push_back({"infinite radius", b, "falloff_radius"});
  }
  {
    pb::Beta b = local_around_top(s);
    *b.add_local() = b.local(0);
    b.mutable_local(1)->mutable_region()->clear_selectors();
    cases.push_back({"empty region", b, "local[1]: region has no selectors"});
  }
  {
    pb::Beta b = local_around_top(s);
    auto* sphere = b.mutable_local(0)->mutable_region()->mutable_selectors(0)->mutable_sphere();
    sphere->mutable_center()->set_x(100);
    sphere->set_radius(0.01);
    cases.push_back({"region selects nothing", b, "selects no vertices"});
  }
  {
    pb::Beta b = local_around_top(s);
    b.mutable_local(0)->mutable_region()->mutable_selectors(0)->mutable_ids()->add_ids(99999999);
    cases.push_back({"vertex id out of range", b, "out of range"});
  }
  {
    pb::Beta b = local_around_top(s);
    b.set_value(1.5);
    cases.push_back({"uniform value", b, "beta must satisfy"});
  }
  for (const auto& c : cases) {
    pb::Session out;
    auto st = t.set_beta(s.name(), c.beta, &out);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << c.what;
    EXPECT_NE(st.error_message().find(c.message), std::string::npos)
        << c.what << ": " << st.error_message();
  }
  // Nothing changed.
  pb::Session now;
  ASSERT_TRUE(t.get_session(s.name(), &now).ok());
  EXPECT_EQ(now.version(), s.version());
  EXPECT_EQ(now.beta().local_size(), 0);
}

TEST(ServiceBeta, SnapshotKeepsAutomaticAndLocal) {
  SingleVertex f;
  pb::Beta b = local_around_top(f.s, 0.2, 0.03);
  b.set_automatic(true);
  b.set_units(pb::BETA_UNITS_RAW);
  pb::Session after;
  auto st = f.t.set_beta(f.s.name(), b, &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(after.beta().automatic());
  EXPECT_EQ(after.beta().local_size(), 1);
  pb::Frame frame;
  ASSERT_TRUE(f.t.update(f.s.name(), 2, {pull()}, &frame).ok());

  pb::Snapshot snap;
  ASSERT_TRUE(f.t.export_session(f.s.name(), &snap).ok());
  EXPECT_TRUE(snap.beta().automatic());
  EXPECT_EQ(snap.beta().value(), after.beta().value());
  EXPECT_EQ(snap.beta().units(), pb::BETA_UNITS_RAW);
  ASSERT_EQ(snap.beta().local_size(), 1);
  EXPECT_EQ(snap.beta().local(0).falloff_radius(), 0.03);

  pb::Session imported;
  st = f.t.import_session(snap, &imported);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(imported.beta().automatic());
  EXPECT_EQ(imported.beta().value(), after.beta().value());
  ASSERT_EQ(imported.beta().local_size(), 1);
  EXPECT_EQ(imported.beta().local(0).SerializeAsString(),
            after.beta().local(0).SerializeAsString());
  EXPECT_EQ(f.t.deformed(imported.name(), pb::MESH_FORMAT_OFF),
            f.t.deformed(f.s.name(), pb::MESH_FORMAT_OFF));
  pb::Frame again;
  ASSERT_TRUE(f.t.update(imported.name(), 2, {pull()}, &again).ok());
  EXPECT_EQ(again.positions(), frame.positions());
}
