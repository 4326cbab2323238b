#include "service/session/session_record.h"

#include "service/session/convert.h"

namespace hdeform::service {

hdeform::state::StoredSession make_record(const Session& session, const std::string& mesh_key,
                                          std::int64_t last_used_unix_ms, std::int64_t* version,
                                          const Session::PendingPose* pending) {
  hdeform::state::StoredSession r;
  r.set_format(kRecordFormat);
  r.set_id(session.id());
  std::int64_t v = 0;
  *r.mutable_snapshot() = session.export_snapshot(false, &v);
  r.set_mesh_key(mesh_key);
  r.set_version(v);
  const SessionTokens t = session.tokens();
  r.set_edit_token_sha256(t.edit.data(), t.edit.size());
  r.set_view_token_sha256(t.view.data(), t.view.size());
  *r.mutable_described() = session.describe();
  pb::ListSnapshotsResponse named = session.list_snapshots();
  r.mutable_snapshots()->Swap(named.mutable_snapshots());
  r.set_create_time_unix_ms(r.described().create_time_unix_ms());
  r.set_update_time_unix_ms(r.described().update_time_unix_ms());
  r.set_last_used_unix_ms(last_used_unix_ms);
  r.mutable_described()->set_version(v);  // describe() may have seen a newer one
  r.mutable_described()->set_observers(0);
  if (pending) {
    v = pending->version;
    r.set_version(v);
    r.mutable_described()->set_version(v);
    for (auto* transforms : {r.mutable_snapshot()->mutable_transforms(),
                             r.mutable_described()->mutable_transforms()}) {
      transforms->Clear();
      for (const auto& h : pending->transforms) to_proto(h, transforms->Add());
    }
    beta_to_proto(pending->beta, r.mutable_snapshot()->mutable_beta());
    beta_to_proto(pending->beta, r.mutable_described()->mutable_beta());
  }
  if (version) *version = v;
  return r;
}

}  // namespace hdeform::service
