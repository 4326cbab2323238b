// A session with two handles for tests of several editors, history and snapshots: a 12×12
// grid fixed along y = 0 with a handle at each far corner, on a real server over loopback.
#pragma once

#include "service_fixture.h"

namespace hdeform::testing {


inline std::unique_ptr<grpc::ClientContext> as(const std::string& token) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->AddMetadata("authorization", "Bearer " + token);
  return ctx;
}

inline pb::Participant who(const std::string& id, const std::string& name) {
  pb::Participant p;
  p.set_client_id(id);
  p.set_display_name(name);
  return p;
}

inline pb::Selector box(double x0, double y0, double x1, double y1) {
  pb::Selector s;
  auto* b = s.mutable_box();
  b->mutable_min()->set_x(x0);
  b->mutable_min()->set_y(y0);
  b->mutable_min()->set_z(-1);
  b->mutable_max()->set_x(x1);
  b->mutable_max()->set_y(y1);
  b->mutable_max()->set_z(1);
  return s;
}

// A 12×12 grid (x in [0, π], y in [0, e]) fixed along y = 0 with two handles at the far
// corners: two editors can each drag their own.
struct TwoHandles {
  TestServer t;
  pb::Session s;
  explicit TwoHandles(hdeform::service::ServerOptions options = {}) : t(std::move(options)) {
    EXPECT_TRUE(t.upload(grid_off(12), "grid.off", &s).ok());
    pb::Constraints c;
    *c.mutable_fixed()->add_selectors() = box(-1, -0.01, 4, 0.01);
    *c.add_handles()->add_selectors() = box(-0.01, 2.6, 0.3, 3);
    *c.add_handles()->add_selectors() = box(2.9, 2.6, 3.2, 3);
    pb::Session out;
    const auto st = t.set_constraints(s.name(), c, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
    out.set_edit_token(s.edit_token());
    out.set_view_token(s.view_token());
    s = out;
  }
  // The same session in another server (restarted on the same state).
  TwoHandles(hdeform::service::ServerOptions options, pb::Session existing)
      : t(std::move(options)), s(std::move(existing)) {}
  grpc::Status update(const std::string& client, std::vector<int> handles,
                      std::vector<pb::HandleTransform> ts, pb::Frame* out = nullptr,
                      bool coalesce = false, bool dragging = false) {
    pb::UpdateHandlesRequest r;
    r.set_name(s.name());
    r.set_dragging(dragging);
    r.set_client_id(client);
    r.set_coalesce(coalesce);
    for (int h : handles) r.add_handles(h);
    for (auto& tr : ts) *r.add_transforms() = tr;
    pb::Frame f;
    return t.bare_stub->UpdateHandles(as(s.edit_token()).get(), r, out ? out : &f);
  }
  grpc::Status grab(const pb::Participant& p, std::vector<int> handles, int lease_ms = 0,
                    pb::GrabHandlesResponse* out = nullptr, const std::string& token = "") {
    pb::GrabHandlesRequest r;
    r.set_name(s.name());
    *r.mutable_client() = p;
    for (int h : handles) r.add_handles(h);
    r.set_lease_ms(lease_ms);
    pb::GrabHandlesResponse resp;
    return t.bare_stub->GrabHandles(as(token.empty() ? s.edit_token() : token).get(), r,
                                    out ? out : &resp);
  }
  grpc::Status release(const std::string& client, std::vector<int> handles = {}) {
    pb::ReleaseHandlesRequest r;
    r.set_name(s.name());
    r.set_client_id(client);
    for (int h : handles) r.add_handles(h);
    pb::GrabHandlesResponse resp;
    return t.bare_stub->ReleaseHandles(as(s.edit_token()).get(), r, &resp);
  }
  pb::Session state() {
    pb::Session now;
    EXPECT_TRUE(t.get_session(s.name(), &now).ok());
    return now;
  }
};

inline double tz(const pb::Session& s, int handle) { return s.transforms(handle).translation().z(); }

}  // namespace hdeform::testing
