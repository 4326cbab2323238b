// A session's core: construction, the version and queue checks, β parsing, the solves and
// the description every answer carries. The commands that change a session are in
// session_change.cpp (and the files named after them); see docs/architecture.md.
#include "service/session/session.h"

#include "engine/deform/auto_beta.h"
#include "engine/runtime/elapsed_ms.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>

namespace hdeform::service {

using detail::make_field;

std::int64_t unix_ms_now() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

namespace detail {
std::shared_ptr<const LocalBeta> make_field(const Eigen::VectorXd& local_max, const Beta& uniform) {
  auto field = std::make_shared<LocalBeta>();
  field->beta = local_max.cwiseMax(uniform.value);
  field->units = uniform.units;
  return field;
}
}  // namespace detail

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
                     elapsed_ms(t0),
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
               r.samples.size(), elapsed_ms(t0));
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

SessionPose Session::pose() const {
  if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
  SessionPose out;
  out.name = name_;
  out.mesh = mesh_;
  std::lock_guard lock(mutex_);
  out.cs = cs_;
  out.beta = beta_;
  out.transforms = transforms_;
  out.timeline = timeline_;
  out.version = version_;
  return out;
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
  out->set_observers(observers_.watchers());
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

void Session::close() {
  if (closed_.exchange(true)) return;
  const Observers::Open open = observers_.close();
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
