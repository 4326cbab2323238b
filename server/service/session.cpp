#include "session.h"

#include "auto_beta.h"
#include "convert.h"
#include "errors.h"

#include <spdlog/spdlog.h>

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

// The session's β as a proto (Session, Snapshot; with_local = false for frames: the local
// entries may carry whole .sel files and every frame would repeat them).
void beta_to_proto(const SessionBeta& b, pb::Beta* out, bool with_local = true) {
  out->Clear();
  to_proto(b.uniform, out);
  out->set_automatic(b.automatic);
  if (with_local) *out->mutable_local() = b.local;
}

double ms_between(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

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
      limits_(limits),
      cache_(cache),
      strand_(std::make_shared<Strand>(pool)) {
  create_ms_ = update_ms_ = unix_ms_now();
  touch();
}

void Session::touch() { last_used_ns_.store(steady_ns()); }

std::chrono::steady_clock::time_point Session::last_used() const {
  return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(last_used_ns_.load()));
}

void Session::check_version_locked(std::int64_t expected) const {
  if (expected != 0 && expected != version_)
    fail(grpc::StatusCode::ABORTED, "version conflict: expected " + std::to_string(expected) +
                                        ", session " + name_ + " is at " +
                                        std::to_string(version_));
}

std::shared_ptr<const ConstraintSet> Session::constraint_set_for(const Constraints& c,
                                                                 const std::string& key) {
  auto make = [&]() -> std::shared_ptr<const ConstraintSet> {
        const auto t0 = std::chrono::steady_clock::now();
        auto cs = std::make_shared<ConstraintSet>(mesh_->prepared, c);  // non-const: prepare()
        spdlog::info("{}: constraint set {} built in {:.1f} ms ({} fixed, {} handle(s))", name_,
                     key,
                     std::chrono::duration<double, std::milli>(
                         std::chrono::steady_clock::now() - t0)
                         .count(),
                     c.fixed.size(), c.handles.size());
        return cs;
  };
  auto cs = cache_.get_or_create<ConstraintSet>(
      key, make, [](const ConstraintSet& cs) { return cs.memory_bytes(); });
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
                                     std::int64_t expected_version) {
  touch();
  SessionBeta beta;
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    beta = beta_;
  }
  const Constraints resolved = resolve_constraints(constraints, mesh_->prepared->mesh().V,
                                                   mesh_->layout->base_to_engine(), limits_);
  const std::string key = "cs/" + mesh_->hash + "/" + constraints_digest(resolved);
  auto cs = constraint_set_for(resolved, key);
  // ConstraintSet is shared: prepare() is thread-safe (it builds each β once). An automatic
  // β keeps its pick (the new handles are at rest: nothing to pick from yet).
  prepare_beta(*cs, beta);
  cache_.update_size(key, cs->memory_bytes());
  pb::Session out;
  {
    std::lock_guard lock(mutex_);
    cs_ = cs;
    cs_key_ = key;
    given_ = constraints;
    transforms_.assign(cs->num_handles(), HandleTransform{});
    changed_locked(&out);
  }
  broadcast_state();
  return out;
}

pb::Session Session::set_beta(const pb::Beta& beta_msg, std::int64_t expected_version) {
  touch();
  SessionBeta beta = parse_beta(beta_msg);
  std::shared_ptr<const ConstraintSet> cs;
  std::vector<HandleTransform> transforms;
  std::string key;
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    cs = cs_;
    transforms = transforms_;
    key = cs_key_;
  }
  if (beta.automatic) {
    if (!cs)
      fail(grpc::StatusCode::FAILED_PRECONDITION,
           "automatic beta is picked at the session's handle transforms: call SetConstraints "
           "first");
    pick_beta(beta, *cs, transforms);
  }
  if (cs) {
    prepare_beta(*cs, beta);
    cache_.update_size(key, cs->memory_bytes());
  }
  pb::Session out;
  {
    std::lock_guard lock(mutex_);
    beta_ = std::move(beta);
    changed_locked(&out);
  }
  broadcast_state();
  return out;
}

std::shared_ptr<pb::Frame> Session::update(const Update& u) {
  touch();
  const auto t0 = std::chrono::steady_clock::now();
  std::shared_ptr<const ConstraintSet> cs;
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
  std::string key;
  const bool keep = u.keep_transforms_if_empty && (!u.transforms || u.transforms->empty());
  {
    std::lock_guard lock(mutex_);
    // A Deform stream holds its session directly: after DeleteSession it must stop too.
    if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    check_version_locked(u.expected_version);
    cs = cs_;
    beta = beta_;
    key = cs_key_;
    if (keep) transforms = transforms_;
  }
  if (!keep) {
    static const google::protobuf::RepeatedPtrField<pb::HandleTransform> kNone;
    transforms = from_proto(u.transforms ? *u.transforms : kNone, *cs);
  }
  bool beta_changed = false;
  if (u.beta) {
    SessionBeta b = parse_beta(*u.beta);
    if (b.automatic) pick_beta(b, *cs, transforms);  // at the transforms being committed
    beta_changed = !b.same_as(beta);
    beta = std::move(b);
  }
  std::shared_ptr<hdeform::Frame> frame = solve_move(*cs, transforms, beta, u);
  if (beta_changed) cache_.update_size(key, cs->memory_bytes());

  auto out = std::make_shared<pb::Frame>();
  mesh_->layout->fill(*frame, out.get());
  out->set_session(name_);
  out->set_sequence(u.sequence);
  beta_to_proto(beta, out->mutable_beta(), false);
  {
    std::lock_guard lock(mutex_);
    if (cs_ != cs) {
      // SetConstraints cannot interleave (same strand); this guards against misuse.
      fail(grpc::StatusCode::ABORTED, "constraints changed during the update");
    }
    transforms_ = std::move(transforms);
    beta_ = beta;
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
  }
  out->set_solve_ms(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  if (beta_changed) broadcast_state();
  if (observers() > 0) {
    auto event = std::make_shared<pb::SessionEvent>();
    *event->mutable_frame() = *out;
    broadcast(std::move(event));
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

pb::Frame Session::superseded_frame(std::int64_t sequence) const {
  pb::Frame out;
  out.set_session(name_);
  out.set_sequence(sequence);
  out.set_version(version());
  out.set_superseded(true);
  return out;
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

std::string Session::mesh_file(bool rest, pb::MeshFormat format) {
  touch();
  const MeshFileFormat f = file_format(format);
  if (rest && f == MeshFileFormat::glb) return mesh_->layout->base_glb();
  const Vertices V = rest ? mesh_->prepared->mesh().V : deformed_positions();
  return mesh_->layout->mesh_file(f, V);
}

pb::Snapshot Session::export_snapshot(bool include_mesh, std::int64_t* version) const {
  pb::Snapshot s;
  s.set_mesh_hash(mesh_->hash);
  s.set_library_mesh(mesh_->library_name);
  s.set_filename(mesh_->filename);
  if (include_mesh && mesh_->file_bytes) s.set_mesh_bytes(*mesh_->file_bytes);
  std::lock_guard lock(mutex_);
  if (version) *version = version_;
  if (cs_) *s.mutable_constraints() = given_;
  beta_to_proto(beta_, s.mutable_beta());
  for (const auto& t : transforms_) to_proto(t, s.add_transforms());
  return s;
}

void Session::restore(const pb::Snapshot& s) {
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
  std::lock_guard lock(mutex_);
  transforms_ = std::move(transforms);
  ++version_;
  last_frame_.reset();
}

void Session::adopt(std::int64_t version, const SessionTokens& tokens, std::int64_t create_ms,
                    std::int64_t update_ms) {
  std::lock_guard lock(mutex_);
  version_ = version;
  tokens_ = tokens;
  create_ms_ = create_ms;
  update_ms_ = update_ms;
}

Access Session::grant(const std::vector<TokenHash>& token_hashes) const {
  std::lock_guard lock(mutex_);
  return tokens_.grant(token_hashes);
}

IssuedTokens Session::rotate_tokens() {
  std::lock_guard lock(mutex_);
  return tokens_.issue();
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
  out->set_mesh_name(mesh_->display_name());
  out->set_vertex_count(mesh_->layout->vertex_count());
  out->set_triangle_count(mesh_->layout->triangle_count());
  out->set_version(version_);
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

void Session::broadcast(std::shared_ptr<const pb::SessionEvent> event) {
  std::vector<std::shared_ptr<EventSink>> sinks;
  {
    std::lock_guard lock(mutex_);
    sinks = watchers_;
  }
  for (auto& s : sinks) s->push(event);
}

void Session::broadcast_state() {
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_state() = describe();
  broadcast(std::move(event));
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
  broadcast_state();  // the others see the new observer count
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
  std::vector<std::shared_ptr<EventSink>> sinks;
  {
    std::lock_guard lock(mutex_);
    sinks.swap(watchers_);
  }
  auto event = std::make_shared<pb::SessionEvent>();
  event->set_deleted(name_);
  for (auto& s : sinks) {
    s->push(event);
    s->close();
  }
}

}  // namespace hdeform::service
