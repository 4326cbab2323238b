#include "service/session/session.h"

#include "service/session/history_record.h"

#include "service/session/handle_update.h"

#include "engine/deform/auto_beta.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <spdlog/spdlog.h>

#include <cctype>
#include <charconv>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <set>

namespace hdeform::service {

std::int64_t unix_ms_now() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

namespace {
std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

MeshFileFormat file_format(pb::MeshFormat f) {
  switch (f) {
    case pb::MESH_FORMAT_OBJ: return MeshFileFormat::obj;
    case pb::MESH_FORMAT_OFF: return MeshFileFormat::off;
    case pb::MESH_FORMAT_PLY: return MeshFileFormat::ply;
    case pb::MESH_FORMAT_GLB: return MeshFileFormat::glb;
    default: break;
  }
  fail(grpc::StatusCode::INVALID_ARGUMENT, "unknown mesh format " + std::to_string(f));
}

const char* kNoConstraints = "the session has no constraints yet: call SetConstraints first";

std::shared_ptr<const LocalBeta> make_field(const Eigen::VectorXd& local_max, const Beta& uniform) {
  auto field = std::make_shared<LocalBeta>();
  field->beta = local_max.cwiseMax(uniform.value);
  field->units = uniform.units;
  return field;
}

double ms_between(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

void beta_to_proto(const SessionBeta& b, pb::Beta* out, bool with_local) {
  out->Clear();
  to_proto(b.uniform, out);
  out->set_automatic(b.automatic);
  if (with_local) *out->mutable_local() = b.local;
}

bool SessionBeta::same_as(const SessionBeta& o) const {
  if (uniform.value != o.uniform.value || uniform.units != o.uniform.units ||
      automatic != o.automatic || local.size() != o.local.size())
    return false;
  for (int i = 0; i < local.size(); ++i)
    if (local.Get(i).SerializeAsString() != o.local.Get(i).SerializeAsString()) return false;
  return true;
}

Session::Session(std::string id, std::shared_ptr<const MeshRef> mesh, WorkerPool& pool,
                 Cache& cache, const RequestLimits& limits)
    : id_(std::move(id)),
      name_("sessions/" + id_),
      mesh_(std::move(mesh)),
      // Until named: a neutral name in the file's format (a shared MeshRef's own name is
      // another uploader's).
      upload_name_(mesh_->library_name.empty()
                       ? "upload" + std::filesystem::path(mesh_->filename).extension().string()
                       : ""),
      limits_(limits),
      cache_(cache),
      strand_(std::make_shared<Strand>(pool)),
      history_(History::Limits{limits.max_history, 64u << 20}),
      roster_(Roster::Limits{limits.max_watchers, std::chrono::milliseconds(5000),
                             limits.max_lease}) {
  create_ms_ = update_ms_ = unix_ms_now();
  touch();
}

void Session::touch() { last_used_ns_.store(steady_ns()); }

std::chrono::steady_clock::time_point Session::last_used() const {
  return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(last_used_ns_.load()));
}

void Session::check_queue_locked(std::size_t limit) const {
  const std::size_t waiting = strand_->queued();
  if (waiting >= limit)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         name_ + " has " + std::to_string(waiting) +
             " calls waiting, the limit (--max-session-queue); retry when an answer arrives");
}

void Session::check_version_locked(std::int64_t expected) const {
  if (expected != 0 && expected != version_)
    fail(grpc::StatusCode::ABORTED, "version conflict: expected " + std::to_string(expected) +
                                        ", session " + name_ + " is at " +
                                        std::to_string(version_));
}

void Session::check_config_version_locked(std::int64_t expected) const {
  if (expected != 0 && expected != config_version_)
    fail(grpc::StatusCode::ABORTED,
         "the constraints or beta of " + name_ + " changed since config_version " +
             std::to_string(expected) + " (now " + std::to_string(config_version_) +
             "): another change came first; reload the session (GetSession) and retry");
}

std::shared_ptr<const ConstraintSet> Session::constraint_set_for(const Constraints& c,
                                                                 const std::string& key) {
  auto make = [&]() -> std::shared_ptr<const ConstraintSet> {
        const auto t0 = std::chrono::steady_clock::now();
        auto cs = std::make_shared<ConstraintSet>(mesh_->prepared, c);  // non-const: prepare()
        cs->charge_to(cache_.factor_budget());
        spdlog::info("{}: constraint set {} built in {:.1f} ms ({} fixed, {} handle(s))", name_,
                     key,
                     std::chrono::duration<double, std::milli>(
                         std::chrono::steady_clock::now() - t0)
                         .count(),
                     c.fixed.size(), c.handles.size());
        return cs;
  };
  auto cs = cache_.get_or_create<ConstraintSet>(
      key, make, [](const ConstraintSet& cs) { return cs.base_bytes(); });
  // A hit is verified: the set is shared with other sessions and must be exactly ours.
  if (&cs->mesh() != mesh_->prepared.get() || cs->constraints().fixed != c.fixed ||
      cs->constraints().handles != c.handles) {
    spdlog::warn("{}: cache entry {} holds other constraints; building a private set", name_, key);
    cs = make();
  }
  return cs;
}

SessionBeta Session::parse_beta(const pb::Beta& b, bool keep_automatic_value) const {
  SessionBeta out;
  out.automatic = b.automatic();
  if (out.automatic && !keep_automatic_value)
    out.uniform = Beta{0.0, units_from(b.units())};  // `value` is ignored: it gets picked
  else
    out.uniform = from_proto(b);
  if (b.local_size() == 0) return out;
  check_limit(static_cast<std::size_t>(b.local_size()), limits_.max_local_beta,
              "beta.local entries", "--max-local-beta");
  out.local = b.local();
  const PreparedMesh& pm = *mesh_->prepared;
  auto local_max = std::make_shared<Eigen::VectorXd>(Eigen::VectorXd::Zero(pm.m()));
  for (int i = 0; i < b.local_size(); ++i) {
    const pb::LocalBeta& e = b.local(i);
    const std::string where = "beta.local[" + std::to_string(i) + "]";
    if (!std::isfinite(e.beta()) || e.beta() < 0 || e.beta() >= 1)
      throw InvalidInput(where + ": beta must satisfy 0 <= beta < 1, got " +
                         fmt::format("{}", e.beta()));
    if (!std::isfinite(e.falloff_radius()) || e.falloff_radius() < 0)
      throw InvalidInput(where + ": falloff_radius must be finite and >= 0, got " +
                         fmt::format("{}", e.falloff_radius()));
    if (e.region().selectors_size() == 0)
      throw InvalidInput(where + ": region has no selectors");
    const std::vector<int> ids = resolve_region(e.region(), pm.mesh().V, where + " region",
                                                mesh_->layout->base_to_engine(), limits_);
    const Eigen::VectorXd f = e.falloff_radius() > 0
                                  ? falloff_beta(pm, ids, e.beta(), e.falloff_radius())
                                  : region_beta(pm, ids, e.beta());
    *local_max = local_max->cwiseMax(f);
  }
  out.local_max = std::move(local_max);
  out.field = make_field(*out.local_max, out.uniform);
  return out;
}

void Session::pick_beta(SessionBeta& beta, const ConstraintSet& cs,
                        const std::vector<HandleTransform>& transforms) {
  const auto t0 = std::chrono::steady_clock::now();
  AutoBetaParams params;
  params.units = beta.uniform.units;
  // select_beta solves each sample transiently: the shared set's cache is left alone.
  params.cancelled = [this] { return closed(); };
  const AutoBetaResult r = select_beta(cs, std::span(transforms), params);
  beta.uniform.value = r.beta.value;
  if (beta.has_local()) beta.field = make_field(*beta.local_max, beta.uniform);
  spdlog::info("{}: automatic beta picked {} ({}) from {} samples in {:.1f} ms", name_,
               r.beta.value, beta.uniform.units == BetaUnits::raw ? "raw" : "area",
               r.samples.size(), ms_between(t0));
}

void Session::prepare_beta(const ConstraintSet& cs, const SessionBeta& beta) {
  if (beta.field) {
    // No prepare() for fields: one cheap solve at rest builds (and caches) the system.
    const std::vector<HandleTransform> rest(static_cast<std::size_t>(cs.num_handles()));
    cs.update_local(rest, *beta.field, UpdateOptions{.energies = false, .normals = false});
  } else {
    cs.prepare(beta.uniform);
  }
}

std::shared_ptr<hdeform::Frame> Session::solve_move(const ConstraintSet& cs,
                                                    const std::vector<HandleTransform>& transforms,
                                                    const SessionBeta& beta, const Update& u) {
  std::lock_guard lock(move_mutex_);
  std::shared_ptr<hdeform::Frame> frame;
  if (spare_frame_ && spare_frame_.use_count() == 1) frame = std::move(spare_frame_);
  else frame = std::make_shared<hdeform::Frame>();
  const auto now = std::chrono::steady_clock::now();
  UpdateOptions options;
  options.energies = u.energies;
  options.normals = true;
  // While dragging, measures are a side panel's figures: at most every 100 ms (and always on
  // the frame that ends the drag, which is exact).
  options.measures = !u.dragging || now - last_measured_ >= kDragMeasuresPeriod;
  options.precision = u.dragging ? FramePrecision::drag : FramePrecision::exact;
  if (beta.field) cs.update_local(transforms, *beta.field, options, workspace_, *frame);
  else cs.update(transforms, beta.uniform, options, workspace_, *frame);
  if (frame->has_measures) last_measured_ = now;
  return frame;
}

hdeform::Frame Session::solve(const ConstraintSet& cs,
                              const std::vector<HandleTransform>& transforms,
                              const SessionBeta& beta, const UpdateOptions& options) const {
  if (beta.field) return cs.update_local(transforms, *beta.field, options);
  return cs.update(transforms, beta.uniform, options);
}

pb::Session Session::set_constraints(const pb::Constraints& constraints,
                                     std::int64_t expected_version,
                                     std::int64_t expected_config_version,
                                     const std::string& client_id, bool discard_timeline) {
  touch();
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    check_config_version_locked(expected_config_version);
  }
  Change change;
  change.cs = constraint_set_of(constraints, &change.target.cs_key);
  const ConstraintSet& cs = *change.cs;
  {
    std::lock_guard lock(mutex_);
    const std::string key = std::move(change.target.cs_key);
    change.target = edit_state_locked();
    change.target.cs_key = key;
  }
  change.target.given = std::make_shared<const pb::Constraints>(constraints);
  change.target.transforms.assign(cs.num_handles(), HandleTransform{});
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_CONSTRAINTS);
  step.info.set_client_id(client_id);
  step.info.set_summary("constraints: " + std::to_string(cs.constraints().fixed.size()) +
                        " fixed vertices, " + std::to_string(cs.num_handles()) + " handle(s)");
  step.constraints = true;
  change.discard_timeline = discard_timeline;
  return execute(std::move(change));
}

std::shared_ptr<const ConstraintSet> Session::constraint_set_of(const pb::Constraints& given,
                                                                std::string* key) {
  const Constraints resolved = resolve_constraints(given, mesh_->prepared->mesh().V,
                                                   mesh_->layout->base_to_engine(), limits_);
  *key = "cs/" + mesh_->hash + "/" + constraints_digest(resolved);
  return constraint_set_for(resolved, *key);
}

EditState Session::edit_state_locked(const std::string& snapshot) const {
  EditState out{cs_key_, given_, beta_, transforms_, timeline_, nullptr};
  if (!snapshot.empty())
    if (auto it = snapshots_.find(snapshot); it != snapshots_.end()) out.snapshot = it->second;
  return out;
}

std::string Session::author_of(const std::string& client_id) const {
  return client_id.empty() ? "anonymous" : roster_.name_of(client_id);
}

pb::HistoryStep Session::record_locked(Step step) {
  step.info.set_version(version_);
  step.info.set_time_unix_ms(unix_ms_now());
  step.info.set_author(author_of(step.info.client_id()));
  step.info.set_beta_changed(step.beta);
  step.info.set_timeline_changed(step.timeline);
  if (!step.snapshot.empty()) step.info.set_snapshot(step.snapshot);
  step.info.mutable_handles()->Assign(step.handles.begin(), step.handles.end());
  return history_.record(std::move(step));
}

pb::Session Session::execute(Change change) {
  EditState& target = change.target;
  Step& step = change.step;
  std::shared_ptr<const ConstraintSet>& cs = change.cs;
  std::string current_key;
  {
    std::lock_guard lock(mutex_);
    current_key = cs_key_;
    if (!cs && target.cs_key == cs_key_) cs = cs_;
  }
  // Build and account, outside the lock: the set and the β factorization the target needs
  // (ConstraintSet::prepare is thread-safe; an automatic β keeps its pick).
  if (!cs && !target.cs_key.empty()) {
    std::string key;
    cs = constraint_set_of(*target.given, &key);
    target.cs_key = key;
  }
  if (cs && step.changes_pose()) {
    prepare_beta(*cs, target.beta);
    cache_.update_size(target.cs_key, cs->base_bytes());
  }
  const bool constraints_changed = target.cs_key != current_key;
  pb::Session out;
  pb::HistoryStep info;
  bool pose_changed = false;
  Applied applied;
  {
    std::lock_guard lock(mutex_);
    // Check: everything below must succeed once it starts.
    const bool drops_keys = constraints_changed && !step.timeline && timeline_->keys_size() > 0;
    if (drops_keys && !change.discard_timeline &&
        timeline_->client_id() != step.info.client_id())
      fail(grpc::StatusCode::ABORTED,
           "new constraints would drop the timeline's " + std::to_string(timeline_->keys_size()) +
               " key(s) set by " + timeline_->author() +
               " (a key's transforms are per handle): send discard_timeline to drop them "
               "anyway (Undo brings them back)");
    if (!step.snapshot.empty() && target.snapshot && !snapshots_.count(step.snapshot))
      check_limit(snapshots_.size() + 1, limits_.max_snapshots, "named snapshots of " + name_,
                  "--max-snapshots");

    // Apply.
    step.before = edit_state_locked(step.snapshot);
    const bool beta_changed = !beta_.same_as(target.beta);
    step.beta = step.beta || beta_changed;
    if (step.constraints || constraints_changed) {
      step.constraints = true;
      step.handles.clear();
      for (int j = 0; j < (cs ? cs->num_handles() : 0); ++j) step.handles.push_back(j);
    }
    applied = applied_locked(step.snapshot);
    pose_changed = step.changes_pose();
    if (pose_changed) {
      cs_ = cs;
      cs_key_ = target.cs_key;
      given_ = target.given;
      beta_ = target.beta;
      transforms_ = target.transforms;
      if (constraints_changed || beta_changed) ++config_version_;
      changed_locked(&out);
    } else {
      describe_locked(&out);
    }
    if (drops_keys) {
      auto cleared = std::make_shared<pb::Timeline>();
      cleared->set_version(version_);
      cleared->set_author(author_of(step.info.client_id()));
      cleared->set_client_id(step.info.client_id());
      target.timeline = std::move(cleared);
      step.timeline = true;
    }
    if (step.timeline) timeline_ = target.timeline;
    if (!step.snapshot.empty()) {
      if (target.snapshot) snapshots_[step.snapshot] = target.snapshot;
      else snapshots_.erase(step.snapshot);
    }
    step.after = std::move(target);
  }
  // Store: a refusal puts the session back as it was; nothing was recorded or told.
  if (store_gate_) store(nullptr, &applied, step.snapshot);  // applied: no lock to hold
  {
    std::lock_guard lock(mutex_);
    if (step.constraints) history_.forget_drags();
    info = record_locked(std::move(step));
  }
  // Broadcast.
  if (pose_changed) broadcast_state();
  broadcast_step(info);
  if (info.timeline_changed()) broadcast_timeline();
  if (constraints_changed && roster_.release_all()) broadcast_presence();  // renumbered
  if (change.send_frame && pose_changed) broadcast_frame(info.client_id());
  return out;
}

std::unique_lock<std::mutex> Session::store(const PendingPose* pose, Applied* applied,
                                            const std::string& snapshot) {
  try {
    return store_gate_(*this, pose);
  } catch (...) {
    std::lock_guard lock(mutex_);
    if (applied) put_back_locked(std::move(*applied), snapshot);
    // A write that timed out may still land: the refused change's version is never used
    // again, so this copy's next record (the flusher's) overrides whatever the store holds.
    ++version_;
    throw;
  }
}

Session::Applied Session::applied_locked(const std::string& snapshot) const {
  return {edit_state_locked(snapshot), cs_, version_, config_version_, update_ms_, last_frame_,
          last_frame_version_};
}

void Session::put_back_locked(Applied a, const std::string& snapshot) {
  cs_ = std::move(a.cs);
  cs_key_ = std::move(a.state.cs_key);
  given_ = std::move(a.state.given);
  beta_ = std::move(a.state.beta);
  transforms_ = std::move(a.state.transforms);
  timeline_ = std::move(a.state.timeline);
  if (!snapshot.empty()) {
    if (a.state.snapshot) snapshots_[snapshot] = std::move(a.state.snapshot);
    else snapshots_.erase(snapshot);
  }
  version_ = a.version;
  config_version_ = a.config_version;
  update_ms_ = a.update_ms;
  last_frame_ = std::move(a.last_frame);
  last_frame_version_ = a.last_frame_version;
}

pb::Session Session::set_beta(const pb::Beta& beta_msg, std::int64_t expected_version,
                              std::int64_t expected_config_version,
                              const std::string& client_id) {
  touch();
  SessionBeta beta = parse_beta(beta_msg);
  EditState target;
  std::shared_ptr<const ConstraintSet> cs;
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    check_config_version_locked(expected_config_version);
    cs = cs_;
    target = edit_state_locked();
  }
  if (beta.automatic) {
    if (!cs)
      fail(grpc::StatusCode::FAILED_PRECONDITION,
           "automatic beta is picked at the session's handle transforms: call SetConstraints "
           "first");
    pick_beta(beta, *cs, target.transforms);
  }
  if (beta.same_as(target.beta)) {  // nothing changes: no step, no new version
    std::lock_guard lock(mutex_);
    pb::Session out;
    describe_locked(&out);
    return out;
  }
  Change change;
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_BETA);
  step.info.set_client_id(client_id);
  char buf[96];
  std::snprintf(buf, sizeof buf, "beta %.6g -> %.6g (%s)%s", target.beta.uniform.value,
                beta.uniform.value, beta.uniform.units == BetaUnits::raw ? "raw" : "area",
                beta.automatic ? ", automatic" : "");
  step.info.set_summary(buf);
  step.beta = true;
  target.beta = std::move(beta);
  change.target = std::move(target);
  change.cs = std::move(cs);
  return execute(std::move(change));
}

std::vector<int> Session::handle_indices(
    const google::protobuf::RepeatedField<std::int32_t>& handles, const char* op) const {
  std::lock_guard lock(mutex_);
  if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
  const int n = cs_->num_handles();
  std::vector<bool> seen(static_cast<std::size_t>(n), false);
  std::vector<int> out;
  for (int i = 0; i < handles.size(); ++i) {
    const int h = handles.Get(i);
    if (h < 0 || h >= n)
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           std::string(op) + ": handles[" + std::to_string(i) + "] = " + std::to_string(h) +
               " is not a handle of " + name_ + " (it has " + std::to_string(n) + ")");
    if (seen[static_cast<std::size_t>(h)])
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           std::string(op) + ": handles names handle " + std::to_string(h) + " twice");
    seen[static_cast<std::size_t>(h)] = true;
    out.push_back(h);
  }
  return out;
}

Session::Move Session::begin_move(const Update& u) {
  Move m;
  const bool keep = u.keep_transforms_if_empty && (!u.transforms || u.transforms->empty());
  {
    std::lock_guard lock(mutex_);
    // A Deform stream holds its session directly: after DeleteSession it must stop too.
    if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    check_version_locked(u.expected_version);
    m.cs = cs_;
    m.beta = beta_;
    m.key = cs_key_;
    m.transforms = transforms_;  // updates run on the strand: nothing moves them meanwhile
    m.version = version_;
    if (u.sequenced && u.coalesce && u.sequence > 0) {
      const auto last = sequences_.last(u.client_id);
      if (last && u.sequence <= last->sequence) m.newer = last;
    }
  }
  if (keep || m.newer) return m;
  static const google::protobuf::RepeatedPtrField<pb::HandleTransform> kNone;
  static const google::protobuf::RepeatedField<std::int32_t> kAll;
  m.moved = apply_handle_update(u.handles ? *u.handles : kAll,
                                u.transforms ? *u.transforms : kNone, *m.cs, m.transforms);
  roster_.check_move(u.client_id, m.moved, Roster::Clock::now());
  return m;
}

pb::Frame Session::supersede(const Update& u) {
  touch();
  Move m = begin_move(u);
  std::unique_lock<std::mutex> stored;
  if (store_gate_ && !m.newer) {
    const PendingPose pose{m.transforms, m.beta, m.version + 1, false};
    stored = store(&pose);
  }
  std::lock_guard lock(mutex_);
  if (cs_ == m.cs && !m.newer) {
    history_.drag_moved(u.client_id, m.moved, transforms_);  // the newer update ends the step
    transforms_ = std::move(m.transforms);
    ++version_;  // the newer update's frame follows at once
    last_frame_.reset();
    if (u.sequenced && u.sequence > 0) sequences_.applied(u.client_id, {u.sequence, u.dragging});
  }
  return superseded_locked(u);
}

pb::Frame Session::superseded_locked(const Update& u) const {
  pb::Frame out;
  out.set_session(name_);
  out.set_sequence(u.sequence);
  out.set_version(version_);
  out.set_client_id(u.client_id);
  out.set_superseded(true);
  return out;
}

std::shared_ptr<pb::Frame> Session::update(const Update& given) {
  touch();
  const auto t0 = std::chrono::steady_clock::now();
  Move m = begin_move(given);
  Update u = given;
  if (m.newer) {
    // Stale: the client's newer update was applied. If it was solved, nothing is left to do;
    // if it was superseded by this one (it arrived first), solve its pose as it asked.
    std::lock_guard lock(mutex_);
    if (last_frame_ && last_frame_version_ == version_)
      return std::make_shared<pb::Frame>(superseded_locked(u));
    u.dragging = m.newer->dragging;
  }
  const auto& cs = m.cs;
  const auto& key = m.key;
  SessionBeta& beta = m.beta;
  std::vector<HandleTransform>& transforms = m.transforms;
  bool beta_changed = false;
  if (u.beta) {
    SessionBeta b = parse_beta(*u.beta);
    if (b.automatic) pick_beta(b, *cs, transforms);  // at the transforms being committed
    beta_changed = !b.same_as(beta);
    beta = std::move(b);
  }
  std::shared_ptr<hdeform::Frame> frame = solve_move(*cs, transforms, beta, u);
  if (beta_changed) cache_.update_size(key, cs->base_bytes());

  // Stored first where an answered move must be durable: a refusal leaves nothing applied.
  std::unique_lock<std::mutex> stored;
  if (store_gate_) {
    const PendingPose pose{transforms, beta, m.version + 1, beta_changed};
    stored = store(&pose);
  }
  auto out = std::make_shared<pb::Frame>();
  pb::HistoryStep recorded;
  mesh_->layout->fill(*frame, out.get());
  out->set_session(name_);
  out->set_sequence(u.sequence);
  out->set_client_id(u.client_id);
  for (const auto& t : transforms) to_proto(t, out->add_transforms());
  beta_to_proto(beta, out->mutable_beta(), false);
  {
    std::lock_guard lock(mutex_);
    if (cs_ != cs) {
      // SetConstraints cannot interleave (same strand); this guards against misuse.
      fail(grpc::StatusCode::ABORTED, "constraints changed during the update");
    }
    // History: a drag is one step, from its first frame's before to its last frame.
    history_.drag_moved(u.client_id, m.moved, transforms_);
    std::map<int, HandleTransform> started;
    if (!u.dragging) started = history_.end_drag(u.client_id);
    bool moved_any = false;
    for (const auto& [h, t] : started)
      moved_any = moved_any || !same_transform(t, transforms[static_cast<std::size_t>(h)]);
    std::optional<Step> step_made;
    if (moved_any || beta_changed) {
      Step& step = step_made.emplace();
      step.before = edit_state_locked();
      for (const auto& [h, t] : started) {
        // A handle sent back to where it was (or a frame refresh) is not a change.
        if (same_transform(t, transforms[static_cast<std::size_t>(h)])) continue;
        step.before.transforms[static_cast<std::size_t>(h)] = t;
        step.handles.push_back(h);
      }
      step.beta = beta_changed;
      step.after = edit_state_locked();
      step.after.beta = beta;
      step.after.transforms = transforms;
      step.info.set_kind(step.handles.empty() ? pb::STEP_KIND_BETA : pb::STEP_KIND_MOVE);
      step.info.set_client_id(u.client_id);
      std::string summary;
      for (int h : step.handles) summary += (summary.empty() ? "moved handle " : ", ") + std::to_string(h);
      if (beta_changed) summary += std::string(summary.empty() ? "" : "; ") + "beta changed";
      step.info.set_summary(summary);
    }
    transforms_ = std::move(transforms);
    beta_ = beta;
    if (u.sequenced && u.sequence > 0 && !m.newer)
      sequences_.applied(u.client_id, {u.sequence, u.dragging});
    if (beta_changed) ++config_version_;
    ++version_;
    {
      std::lock_guard moves(move_mutex_);  // the old frame's buffers serve a later move
      if (last_frame_ && last_frame_.use_count() == 1)
        spare_frame_ = std::const_pointer_cast<hdeform::Frame>(std::move(last_frame_));
    }
    last_frame_ = frame;
    last_frame_version_ = version_;
    update_ms_ = unix_ms_now();
    out->set_version(version_);
    if (step_made) recorded = record_locked(std::move(*step_made));
  }
  out->set_solve_ms(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  if (beta_changed) broadcast_state();
  if (recorded.id() != 0) broadcast_step(recorded);
  if (observers() > 0) {
    auto event = std::make_shared<pb::SessionEvent>();
    *event->mutable_frame() = *out;
    broadcast(std::move(event));
  }
  if (u.float64) {
    auto out64 = std::make_shared<pb::Frame>();
    copy_frame_header(*out, out64.get());
    out64->set_encoding(pb::FRAME_ENCODING_FLOAT64);
    out64->set_positions(mesh_->layout->pack_vertices64(frame->positions));
    if (frame->normals.rows() == frame->positions.rows())
      out64->set_normals(mesh_->layout->pack_vertices64(frame->normals));
    out64->set_energies(out->energies());
    return out64;
  }
  return out;
}

std::unique_ptr<Session::CoalesceTicket> Session::coalesce_ticket(std::size_t limit) {
  if (coalesce_waiting_.fetch_add(1) >= limit) {
    const std::size_t waiting = --coalesce_waiting_;
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         name_ + " has " + std::to_string(waiting) +
             " coalescing updates waiting, the limit (--max-pending-updates); send the next "
             "one when an answer arrives");
  }
  return std::make_unique<CoalesceTicket>(*this, ++coalesce_newest_);
}

Session::SweepPlan Session::sweep_plan(const pb::SweepRequest& request) const {
  if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
  if (request.betas_size() == 0) throw InvalidInput("Sweep: betas is empty");
  check_limit(static_cast<std::size_t>(request.betas_size()), limits_.max_sweep_betas,
              "Sweep betas", "--max-sweep-betas");
  SweepPlan plan;
  SessionBeta session_beta;
  {
    std::lock_guard lock(mutex_);
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    plan.cs = cs_;
    plan.transforms = transforms_;
    session_beta = beta_;
  }
  if (request.transforms_size() > 0) plan.transforms = from_proto(request.transforms(), *plan.cs);
  for (int i = 0; i < request.betas_size(); ++i) {
    try {
      plan.betas.push_back(beta_from(request.betas(i), request.units()));
    } catch (const InvalidInput& e) {
      throw InvalidInput("Sweep betas[" + std::to_string(i) + "]: " + e.what());
    }
  }
  // The session's local entries apply at every β (value = that β), in the sweep's units.
  if (session_beta.has_local()) {
    const BetaUnits from = session_beta.uniform.units, to = units_from(request.units());
    const PreparedMesh& pm = *mesh_->prepared;
    plan.local_max = session_beta.local_max->unaryExpr(
        [&](double v) { return convert_beta(pm, v, from, to); });
  }
  return plan;
}

void Session::sweep_row(const SweepPlan& plan, const Beta& b, pb::SweepRow* row) const {
  const UpdateOptions options{.energies = false, .normals = false};
  // Transient: a sweep's factorizations are freed after each β and never enter the cache
  // other sessions share (at most one extra factorization per running sweep).
  const hdeform::Frame f =
      plan.local_max.size() > 0
          ? plan.cs->update_local(plan.transforms, *make_field(plan.local_max, b), options)
          : plan.cs->update_transient(plan.transforms, b, options);
  row->set_beta(b.value);
  to_proto(f.measures, row->mutable_measures());
}

Vertices Session::deformed_positions() {
  std::shared_ptr<const ConstraintSet> cs;
  std::vector<HandleTransform> transforms;
  SessionBeta beta;
  std::int64_t version;
  {
    std::lock_guard lock(mutex_);
    if (!cs_) return mesh_->prepared->mesh().V;
    // Only an exact frame answers GetMesh (a drag frame is within kDragTolerance only).
    if (last_frame_ && last_frame_version_ == version_ && last_frame_->exact)
      return last_frame_->positions;
    cs = cs_;
    transforms = transforms_;
    beta = beta_;
    version = version_;
  }
  UpdateOptions options;
  options.energies = false;
  options.normals = false;
  auto frame = std::make_shared<const hdeform::Frame>(solve(*cs, transforms, beta, options));
  std::lock_guard lock(mutex_);
  if (version == version_) {
    last_frame_ = frame;
    last_frame_version_ = version;
  }
  return frame->positions;
}

std::string Session::mesh_file(const pb::GetMeshRequest& request) {
  touch();
  const bool rest = request.rest();
  const MeshFileFormat f = file_format(request.format());
  const pb::UpAxis up = request.up();
  const pb::PlyEncoding ply = request.ply_encoding();
  if (up != pb::UP_AXIS_Y && up != pb::UP_AXIS_Z)
    throw InvalidInput("GetMesh: unknown up axis " + std::to_string(up));
  if (ply < pb::PLY_ENCODING_AS_INPUT || ply > pb::PLY_ENCODING_BINARY)
    throw InvalidInput("GetMesh: unknown PLY encoding " + std::to_string(ply));
  WriteOptions options;
  switch (request.glb_compression()) {
    case pb::GLB_COMPRESSION_NONE: break;
    case pb::GLB_COMPRESSION_QUANTIZED: options.glb_compression = GlbCompression::quantized; break;
    case pb::GLB_COMPRESSION_MESHOPT: options.glb_compression = GlbCompression::meshopt; break;
    default:
      throw InvalidInput("GetMesh: unknown glb_compression " +
                         std::to_string(request.glb_compression()));
  }
  const bool compressed = options.glb_compression != GlbCompression::none;
  if (compressed && f != MeshFileFormat::glb)
    throw InvalidInput("GetMesh: glb_compression applies to GLB only, not to " +
                       pb::MeshFormat_Name(request.format()));
  options.up_z = up == pb::UP_AXIS_Z;
  // A binary PLY upload comes back binary: its header says so in the first line after "ply".
  const bool input_binary_ply =
      mesh_->file_bytes && mesh_->file_bytes->compare(0, 24, "ply\nformat binary_little") == 0;
  options.binary_ply = ply == pb::PLY_ENCODING_BINARY ||
                       (ply == pb::PLY_ENCODING_AS_INPUT && input_binary_ply);
  if (rest && f == MeshFileFormat::glb && !options.up_z && !compressed)
    return mesh_->layout->base_glb();
  const Vertices V = rest ? mesh_->prepared->mesh().V : deformed_positions();
  // A glTF upload's deformed GLB is its own file with new positions and normals: UVs,
  // materials, textures, nodes and other primitives stay (glTF is y-up already).
  std::string ext = std::filesystem::path(mesh_->filename).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool gltf_upload =
      mesh_->file_bytes && mesh_->library_name.empty() && (ext == ".glb" || ext == ".gltf");
  if (!rest && f == MeshFileFormat::glb && gltf_upload) {
    if (compressed)
      throw InvalidInput("GetMesh: glb_compression: this session's deformed GLB is its glTF "
                         "upload rewritten (materials and UVs kept), which is not compressed; "
                         "ask GLB_COMPRESSION_NONE, or rest = true for the compressed base mesh");
    return mesh_->layout->input_gltf(*mesh_->file_bytes, mesh_->filename, V);
  }
  return mesh_->layout->mesh_file(f, V, options);
}

pb::Snapshot Session::export_snapshot(bool include_mesh, std::int64_t* version) const {
  pb::Snapshot s;
  s.set_mesh_hash(mesh_->hash);
  s.set_library_mesh(mesh_->library_name);
  s.set_filename(mesh_->library_name.empty() ? upload_name_ : mesh_->filename);
  if (include_mesh && mesh_->file_bytes) s.set_mesh_bytes(*mesh_->file_bytes);
  if (mesh_->repair) s.mutable_repair()->set_merge_tolerance(mesh_->repair->merge_tolerance);
  std::lock_guard lock(mutex_);
  if (version) *version = version_;
  if (cs_ && given_) *s.mutable_constraints() = *given_;
  beta_to_proto(beta_, s.mutable_beta());
  for (const auto& t : transforms_) to_proto(t, s.add_transforms());
  if (timeline_->keys_size() > 0) *s.mutable_timeline() = *timeline_;
  return s;
}

void Session::name_upload(const std::string& filename) {
  if (!mesh_->library_name.empty() || filename.empty()) return;
  upload_name_ = std::filesystem::path(filename).filename().string();
  // The name must keep saying the bytes' format (an export re-imports by it).
  const auto ext = std::filesystem::path(mesh_->filename).extension().string();
  const auto given = std::filesystem::path(upload_name_).extension().string();
  if (!std::equal(ext.begin(), ext.end(), given.begin(), given.end(),
                  [](char a, char b) { return std::tolower(a) == std::tolower(b); }))
    upload_name_ += ext;
}

const std::string& Session::mesh_name() const {
  return mesh_->library_name.empty() ? upload_name_ : mesh_->library_name;
}

void Session::restore(const pb::Snapshot& s) {
  name_upload(s.filename());
  // An automatic β keeps the snapshot's pick (`value`): the restored session deforms exactly
  // as the exported one, whatever transforms the pick was made at.
  SessionBeta beta = s.has_beta() ? parse_beta(s.beta(), true) : SessionBeta{};
  {
    std::lock_guard lock(mutex_);
    beta_ = std::move(beta);
  }
  const bool has_constraints =
      s.has_constraints() &&
      (s.constraints().fixed().selectors_size() > 0 || s.constraints().handles_size() > 0);
  if (!has_constraints) {
    if (s.transforms_size() > 0)
      throw InvalidInput("snapshot has transforms but no constraints");
    return;
  }
  set_constraints(s.constraints(), 0);
  std::shared_ptr<const ConstraintSet> cs;
  {
    std::lock_guard lock(mutex_);
    cs = cs_;
  }
  std::vector<HandleTransform> transforms =
      s.transforms_size() > 0 ? from_proto(s.transforms(), *cs)
                              : std::vector<HandleTransform>(cs->num_handles());
  if (s.timeline().keys_size() > 0) parse_timeline(s.timeline(), *cs);  // a bad one is refused
  std::lock_guard lock(mutex_);
  transforms_ = std::move(transforms);
  timeline_ = std::make_shared<const pb::Timeline>(s.timeline());
  ++version_;
  last_frame_.reset();
}

void Session::adopt(std::int64_t version, const SessionTokens& tokens, std::int64_t create_ms,
                    std::int64_t update_ms) {
  std::lock_guard lock(mutex_);
  version_ = version;
  // Not stored: a client's config_version from before the restart is refused (it reloads).
  config_version_ = version;
  tokens_ = tokens;
  history_.clear();  // adopt_history brings the stored one
  create_ms_ = create_ms;
  update_ms_ = update_ms;
}

void Session::adopt_history(const std::optional<std::string>& stored) {
  std::lock_guard lock(mutex_);
  if (!stored) {
    history_.clear("the session was restored from stored state that kept no history");
    return;
  }
  try {
    hdeform::state::StoredHistory record;
    if (!record.ParseFromString(*stored)) throw std::runtime_error("not a stored history");
    HistoryContext context{edit_state_locked(), snapshots_,
                           [this](const pb::Beta& b) { return parse_beta(b, true); }};
    history_from_record(record, context, history_);
  } catch (const std::exception& e) {
    spdlog::warn("{}: its stored history cannot be read ({}); it starts a new one", name_, e.what());
    history_.clear("the stored history could not be read after a restart: " +
                   std::string(e.what()));
  }
}

std::string Session::history_bytes(std::uint64_t* revision) const {
  // A copy under the lock (steps share their values): the conversion and serialization, up to
  // the history's byte limit, run without holding up the session's edits.
  std::optional<History> copy;
  {
    std::lock_guard lock(mutex_);
    *revision = history_.revision();
    copy.emplace(history_);
  }
  return history_to_record(*copy).SerializeAsString();
}

std::uint64_t Session::history_revision() const {
  std::lock_guard lock(mutex_);
  return history_.revision();
}

Access Session::grant(const std::vector<TokenHash>& token_hashes) const {
  std::lock_guard lock(mutex_);
  return tokens_.grant(token_hashes);
}

IssuedTokens Session::rotate_tokens() {
  IssuedTokens issued;
  std::vector<std::shared_ptr<AuthorizedStream>> revoked;
  {
    std::lock_guard lock(mutex_);
    issued = tokens_.issue();
    // Every stream opened with a token that no longer grants what it needs ends now.
    auto lost = [&](const AuthorizedStream& a) {
      return !a.token_hashes.empty() &&
             static_cast<int>(tokens_.grant(a.token_hashes)) < static_cast<int>(a.needed);
    };
    for (auto it = watchers_.begin(); it != watchers_.end();)
      if (lost(**it)) {
        revoked.push_back(std::move(*it));
        it = watchers_.erase(it);
      } else {
        ++it;
      }
    for (auto it = streams_auth_.begin(); it != streams_auth_.end();) {
      auto live = it->lock();
      if (!live || lost(*live)) {
        if (live) revoked.push_back(std::move(live));
        it = streams_auth_.erase(it);
      } else {
        ++it;
      }
    }
  }
  const grpc::Status why(grpc::StatusCode::UNAUTHENTICATED,
                         "the tokens of " + name_ +
                             " were rotated (RotateTokens): the token this stream was opened "
                             "with no longer grants access; reconnect with a new token");
  for (auto& r : revoked) r->revoke(why);
  if (!revoked.empty()) broadcast_state();  // the observer count changed
  return issued;
}

Session::OpenStreams Session::take_streams() {
  OpenStreams out;
  std::lock_guard lock(mutex_);
  out.watchers.swap(watchers_);
  for (auto& w : streams_auth_)
    if (auto s = w.lock()) out.deform.push_back(std::move(s));
  streams_auth_.clear();
  return out;
}

void Session::end_streams(const grpc::Status& why) {
  const OpenStreams open = take_streams();
  for (const auto& s : open.watchers) s->revoke(why);
  for (const auto& s : open.deform) s->revoke(why);
}

void Session::add_stream(std::weak_ptr<AuthorizedStream> stream) {
  std::lock_guard lock(mutex_);
  std::erase_if(streams_auth_, [](const auto& w) { return w.expired(); });
  streams_auth_.push_back(std::move(stream));
}

SessionTokens Session::tokens() const {
  std::lock_guard lock(mutex_);
  return tokens_;
}

void Session::changed_locked(pb::Session* out) {
  ++version_;
  last_frame_.reset();  // computed for the old state
  update_ms_ = unix_ms_now();
  describe_locked(out);
}

void Session::describe_locked(pb::Session* out) const {
  out->set_name(name_);
  out->set_mesh_hash(mesh_->hash);
  out->set_mesh_name(mesh_name());
  out->set_vertex_count(mesh_->layout->vertex_count());
  out->set_triangle_count(mesh_->layout->triangle_count());
  out->set_version(version_);
  out->set_config_version(config_version_);
  out->set_constrained(cs_ != nullptr);
  if (cs_) {
    to_proto(cs_->constraints(), out->mutable_constraints());
    if (mesh_->layout->remapped()) {
      const Constraints& c = cs_->constraints();
      auto* base = out->mutable_base_constraints();
      const std::vector<int> fixed = mesh_->layout->base_vertices(c.fixed);
      base->mutable_fixed()->mutable_ids()->Add(fixed.begin(), fixed.end());
      for (const auto& h : c.handles) {
        const std::vector<int> ids = mesh_->layout->base_vertices(h);
        base->add_handles()->mutable_ids()->Add(ids.begin(), ids.end());
      }
    }
    for (int j = 0; j < cs_->num_handles(); ++j) to_proto(cs_->centroid(j), out->add_pivots());
  }
  beta_to_proto(beta_, out->mutable_beta());
  for (const auto& t : transforms_) to_proto(t, out->add_transforms());
  out->set_observers(static_cast<int>(watchers_.size()));
  out->set_create_time_unix_ms(create_ms_);
  out->set_update_time_unix_ms(update_ms_);
  to_proto(mesh_->bbox_min, out->mutable_bbox_min());
  to_proto(mesh_->bbox_max, out->mutable_bbox_max());
}

pb::Session Session::describe() const {
  pb::Session out;
  std::lock_guard lock(mutex_);
  describe_locked(&out);
  return out;
}

void Session::broadcast(std::shared_ptr<const pb::SessionEvent> event,
                        const EventSink* except) {
  std::vector<std::shared_ptr<EventSink>> sinks;
  {
    std::lock_guard lock(mutex_);
    sinks = watchers_;
  }
  for (auto& s : sinks)
    if (s.get() != except) s->push(event);
}

void Session::broadcast_state(const EventSink* except) {
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_state() = describe();
  broadcast(std::move(event), except);
}

// ---- history and snapshots ----

namespace {

void check_snapshot_name(const std::string& name, const char* op) {
  const auto chars = std::count_if(name.begin(), name.end(), [](char c) {
    return (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  });
  if (name.empty() || chars > 64)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(op) + ": the snapshot name must have 1–64 characters, got " +
             std::to_string(chars));
  if (std::any_of(name.begin(), name.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u < 0x20 || u == 0x7f;
      }))
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(op) + ": the snapshot name has control characters");
}

}  // namespace

void Session::close_drag(const std::string& client_id) {
  pb::HistoryStep info;
  {
    std::lock_guard lock(mutex_);
    auto started = history_.end_drag(client_id);
    if (started.empty()) return;
    Step step;
    step.before = edit_state_locked();
    step.after = edit_state_locked();
    std::string summary;
    for (const auto& [h, t] : started) {
      if (same_transform(t, step.after.transforms[static_cast<std::size_t>(h)])) continue;
      step.before.transforms[static_cast<std::size_t>(h)] = t;
      step.handles.push_back(h);
      summary += (summary.empty() ? "moved handle " : ", ") + std::to_string(h);
    }
    if (step.handles.empty()) return;  // back where it started: no change
    step.info.set_kind(pb::STEP_KIND_MOVE);
    step.info.set_client_id(client_id);
    step.info.set_summary(summary);
    info = record_locked(std::move(step));
  }
  broadcast_step(info);
}

pb::Session Session::undo(const pb::UndoRequest& request) {
  close_drag(request.client_id());  // an unfinished drag is the step to undo
  return revert(request, true);
}

pb::Session Session::redo(const pb::UndoRequest& request) { return revert(request, false); }

pb::Session Session::revert(const pb::UndoRequest& request, bool undo) {
  touch();
  Change change;
  Step& step = change.step;
  std::int64_t target_id = 0;
  {
    std::lock_guard lock(mutex_);
    const Step& t = undo ? history_.undo_target(request.client_id(), request.step())
                         : history_.redo_target(request.client_id(), request.step());
    // Undo goes from the step's after to its before; redo the other way.
    const EditState& from = undo ? t.after : t.before;
    const EditState& to = undo ? t.before : t.after;
    const EditState current = edit_state_locked(t.snapshot);
    history_.check_unchanged(t, current, from, undo ? "Undo" : "Redo");
    change.target = current;
    apply_side(change.target, t, to);
    step.constraints = t.constraints;
    step.beta = t.beta;
    step.handles = t.handles;
    step.timeline = t.timeline;
    step.snapshot = t.snapshot;
    step.info.set_target(t.info.id());
    step.info.set_summary(std::string(undo ? "undo" : "redo") + " step " +
                          std::to_string(t.info.id()) + " (" + t.info.author() + ": " +
                          t.info.summary() + ")");
    target_id = t.info.id();
  }
  step.info.set_kind(undo ? pb::STEP_KIND_UNDO : pb::STEP_KIND_REDO);
  step.info.set_client_id(request.client_id());
  change.send_frame = true;
  change.discard_timeline = request.discard_timeline();
  pb::Session out = execute(std::move(change));
  std::lock_guard lock(mutex_);
  if (undo) history_.mark_undone(target_id, request.client_id());
  else history_.mark_redone(target_id, request.client_id());
  return out;
}

pb::ListHistoryResponse Session::list_history(const pb::ListHistoryRequest& request) const {
  if (request.page_size() < 0 || request.page_size() > 500)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "ListHistory: page_size must be 0 (50) to 500, got " +
             std::to_string(request.page_size()));
  std::int64_t before = 0;
  if (!request.page_token().empty()) {
    const auto& t = request.page_token();
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), before);
    if (ec != std::errc() || end != t.data() + t.size() || before <= 0)
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           "ListHistory: page_token is not one this server gave (\"" + t.substr(0, 32) + "\")");
  }
  const std::size_t size = request.page_size() == 0 ? 50 : static_cast<std::size_t>(request.page_size());
  pb::ListHistoryResponse out;
  std::lock_guard lock(mutex_);
  auto steps = history_.page(before, size + 1);
  const bool more = steps.size() > size;
  if (more) steps.pop_back();
  for (auto& st : steps) *out.add_steps() = std::move(st);
  if (more) out.set_next_page_token(std::to_string(out.steps(out.steps_size() - 1).id()));
  out.set_total(history_.size());
  return out;
}

pb::NamedSnapshot Session::save_snapshot(const pb::SaveSnapshotRequest& request) {
  touch();
  check_snapshot_name(request.snapshot(), "SaveSnapshot");
  auto named = std::make_shared<pb::NamedSnapshot>();
  named->set_name(request.snapshot());
  named->set_author(author_of(request.client_id()));
  named->set_time_unix_ms(unix_ms_now());
  std::int64_t version = 0;
  *named->mutable_snapshot() = export_snapshot(false, &version);
  named->mutable_snapshot()->clear_timeline();  // a named snapshot is the pose, not the timeline
  named->set_version(version);
  Change change;
  {
    std::lock_guard lock(mutex_);
    change.target = edit_state_locked(request.snapshot());
  }
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_SNAPSHOT_SAVE);
  step.info.set_client_id(request.client_id());
  step.info.set_summary(std::string(change.target.snapshot ? "replaced" : "saved") +
                        " snapshot '" + request.snapshot() + "'");
  step.snapshot = request.snapshot();
  change.target.snapshot = named;
  execute(std::move(change));
  return *named;
}

pb::ListSnapshotsResponse Session::list_snapshots() const {
  pb::ListSnapshotsResponse out;
  std::lock_guard lock(mutex_);
  for (const auto& [name, snap] : snapshots_) *out.add_snapshots() = *snap;
  return out;
}

void Session::delete_snapshot(const std::string& snapshot, const std::string& client_id) {
  touch();
  Change change;
  {
    std::lock_guard lock(mutex_);
    change.target = edit_state_locked(snapshot);
  }
  if (!change.target.snapshot)
    fail(grpc::StatusCode::NOT_FOUND, "DeleteSnapshot: " + name_ + " has no snapshot named '" +
                                          snapshot.substr(0, 64) + "'");
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_SNAPSHOT_DELETE);
  step.info.set_client_id(client_id);
  step.info.set_summary("deleted snapshot '" + snapshot + "'");
  step.snapshot = snapshot;
  change.target.snapshot = nullptr;
  execute(std::move(change));
}

void Session::adopt_snapshots(
    const google::protobuf::RepeatedPtrField<pb::NamedSnapshot>& snapshots) {
  std::lock_guard lock(mutex_);
  for (const auto& s : snapshots) snapshots_[s.name()] = std::make_shared<const pb::NamedSnapshot>(s);
}

pb::Session Session::restore_snapshot(const pb::RestoreSnapshotRequest& request) {
  touch();
  pb::NamedSnapshot named;
  EditState target;
  {
    std::lock_guard lock(mutex_);
    check_config_version_locked(request.expected_config_version());
    auto it = snapshots_.find(request.snapshot());
    if (it == snapshots_.end())
      fail(grpc::StatusCode::NOT_FOUND, "RestoreSnapshot: " + name_ + " has no snapshot named '" +
                                            request.snapshot().substr(0, 64) + "'");
    named = *it->second;
    target = edit_state_locked();
  }
  const pb::Snapshot& snap = named.snapshot();
  std::shared_ptr<const ConstraintSet> cs;
  target.cs_key.clear();
  target.given.reset();
  target.transforms.clear();
  if (snap.has_constraints() &&
      (snap.constraints().fixed().selectors_size() > 0 || snap.constraints().handles_size() > 0)) {
    cs = constraint_set_of(snap.constraints(), &target.cs_key);
    target.given = std::make_shared<const pb::Constraints>(snap.constraints());
    target.transforms = snap.transforms_size() > 0
                            ? from_proto(snap.transforms(), *cs)
                            : std::vector<HandleTransform>(cs->num_handles());
  }
  target.beta = snap.has_beta() ? parse_beta(snap.beta(), true) : SessionBeta{};
  Change change;
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_RESTORE);
  step.info.set_client_id(request.client_id());
  step.info.set_snapshot(named.name());
  step.info.set_summary("restored snapshot '" + named.name() + "'");
  step.constraints = true;
  step.beta = true;
  change.target = std::move(target);
  change.cs = std::move(cs);
  change.send_frame = true;
  change.discard_timeline = request.discard_timeline();
  return execute(std::move(change));
}

void Session::broadcast_step(const pb::HistoryStep& step) {
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_step() = step;
  broadcast(std::move(event));
}

void Session::broadcast_frame(const std::string& client_id) {
  std::shared_ptr<const ConstraintSet> cs;
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
  std::int64_t version = 0;
  {
    std::lock_guard lock(mutex_);
    cs = cs_;
    beta = beta_;
    transforms = transforms_;
    version = version_;
  }
  if (!cs) return;
  const auto t0 = std::chrono::steady_clock::now();
  Update u;
  u.energies = true;
  std::shared_ptr<hdeform::Frame> frame = solve_move(*cs, transforms, beta, u);
  auto out = std::make_shared<pb::Frame>();
  mesh_->layout->fill(*frame, out.get());
  out->set_session(name_);
  out->set_version(version);
  out->set_client_id(client_id);
  for (const auto& t : transforms) to_proto(t, out->add_transforms());
  beta_to_proto(beta, out->mutable_beta(), false);
  out->set_solve_ms(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  {
    std::lock_guard lock(mutex_);
    if (version == version_ && cs == cs_) {
      last_frame_ = frame;
      last_frame_version_ = version;
    }
  }
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_frame() = *out;
  broadcast(std::move(event));
}

pb::HandleWeights Session::handle_weights(int handle) const {
  std::shared_ptr<const ConstraintSet> cs;
  pb::HandleWeights out;
  {
    std::lock_guard lock(mutex_);
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    cs = cs_;
    out.set_version(version_);
  }
  if (handle < 0 || handle >= cs->num_handles())
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "GetHandleWeights: handle " + std::to_string(handle) + " is not a handle of " + name_ +
             " (it has " + std::to_string(cs->num_handles()) + ")");
  out.set_handle(handle);
  out.set_weights(mesh_->layout->pack_vertex_scalars(cs->harmonic_basis(), handle));
  return out;
}

pb::Presence Session::presence() const {
  pb::Presence out;
  roster_.describe(&out);
  out.set_version(version());
  return out;
}

void Session::broadcast_presence() {
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_presence() = presence();
  broadcast(std::move(event));
}

Roster::Claim Session::join(const pb::Participant& who, bool editor) {
  const auto claim = roster_.join(who, editor);
  broadcast_presence();
  return claim;
}

void Session::leave(const std::string& client_id, Roster::Claim claim) {
  const auto left = roster_.leave(client_id, claim);
  if (left == Roster::Left::kDisplaced) return;  // the id is someone else's now
  if (left == Roster::Left::kChanged && !closed_) broadcast_presence();
  close_drag(client_id);  // a vanished client's drag ends where it stopped
}

pb::GrabHandlesResponse Session::grab(const pb::GrabHandlesRequest& request, bool editor) {
  touch();
  Roster::check_participant(request.client(), "GrabHandles");
  if (request.handles_size() == 0)
    fail(grpc::StatusCode::INVALID_ARGUMENT, "GrabHandles: handles is empty");
  const std::vector<int> handles = handle_indices(request.handles(), "GrabHandles");
  const auto now = Roster::Clock::now();
  const auto until = roster_.grab(request.client(), editor, handles,
                                  std::chrono::milliseconds(request.lease_ms()), now);
  broadcast_presence();
  pb::GrabHandlesResponse out;
  *out.mutable_presence() = presence();
  out.set_lease_expire_unix_ms(
      unix_ms_now() + std::chrono::duration_cast<std::chrono::milliseconds>(until - now).count());
  return out;
}

pb::GrabHandlesResponse Session::release(const pb::ReleaseHandlesRequest& request) {
  touch();
  pb::Participant who;
  who.set_client_id(request.client_id());
  Roster::check_participant(who, "ReleaseHandles");
  const std::vector<int> handles = handle_indices(request.handles(), "ReleaseHandles");
  if (roster_.release(request.client_id(), handles)) broadcast_presence();
  close_drag(request.client_id());
  pb::GrabHandlesResponse out;
  *out.mutable_presence() = presence();
  return out;
}

void Session::expire_leases() {
  if (roster_.expire(Roster::Clock::now())) broadcast_presence();
}

bool Session::acquire_delta_watcher(std::size_t limit) {
  int n = delta_watchers_.load();
  do {
    if (static_cast<std::size_t>(n) >= limit) return false;
  } while (!delta_watchers_.compare_exchange_weak(n, n + 1));
  return true;
}

void Session::add_watcher(std::shared_ptr<EventSink> sink) {
  touch();
  auto event = std::make_shared<pb::SessionEvent>();
  {
    std::lock_guard lock(mutex_);
    if (closed_) {
      event->set_deleted(name_);
    } else {
      watchers_.push_back(sink);
      describe_locked(event->mutable_state());
    }
  }
  sink->push(event);
  if (event->has_deleted()) {
    sink->close();
    return;
  }
  auto who = std::make_shared<pb::SessionEvent>();
  *who->mutable_presence() = presence();  // who is here, before anyone moves
  sink->push(std::move(who));
  if (auto t = timeline(); t.keys_size() > 0) {
    auto event = std::make_shared<pb::SessionEvent>();
    *event->mutable_timeline() = std::move(t);
    sink->push(std::move(event));
  }
  // The others see the new observer count; the newcomer's own first event already has it.
  broadcast_state(sink.get());
}

void Session::remove_watcher(const EventSink* sink) {
  bool removed = false;
  {
    std::lock_guard lock(mutex_);
    for (auto it = watchers_.begin(); it != watchers_.end(); ++it)
      if (it->get() == sink) {
        watchers_.erase(it);
        removed = true;
        break;
      }
  }
  touch();
  if (removed && !closed_) broadcast_state();
}

int Session::observers() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(watchers_.size());
}

void Session::close() {
  if (closed_.exchange(true)) return;
  const OpenStreams open = take_streams();
  auto event = std::make_shared<pb::SessionEvent>();
  event->set_deleted(name_);
  for (const auto& s : open.watchers) {  // watchers hear why, then end normally
    s->push(event);
    s->close();
  }
  const grpc::Status gone(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
  for (const auto& s : open.deform) s->revoke(gone);
}

}  // namespace hdeform::service
