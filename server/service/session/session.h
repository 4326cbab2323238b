// One editing session: a shared mesh, a shared constraint set, β, one transform per handle,
// a version, and its observers. Mutations and solves run on the session's strand (one at
// a time, on the worker pool); describe() and the observer list may be used from any
// thread.
#pragma once

#include "engine/deform/deformer.h"
#include "hdeform/v1/deform.pb.h"
#include "service/access/access.h"
#include "service/frames/encoded_frames.h"
#include "service/infra/cache.h"
#include "service/infra/request_limits.h"
#include "service/infra/worker_pool.h"
#include "service/session/client_sequences.h"
#include "service/session/history.h"
#include "service/session/mesh_library.h"
#include "service/session/observers.h"
#include "service/session/request_log.h"
#include "service/session/roster.h"
#include "service/session/session_pose.h"
#include "service/session/timeline.h"

#include <google/protobuf/repeated_field.h>
#include <grpcpp/support/status.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

// While a drag goes on, a frame carries measures only if the last measured one is this old.
inline constexpr std::chrono::milliseconds kDragMeasuresPeriod{100};

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(std::string id, std::shared_ptr<const MeshRef> mesh, WorkerPool& pool, Cache& cache,
          const RequestLimits& limits = {});

  const std::string& id() const { return id_; }
  const std::string& name() const { return name_; }  // "sessions/{id}"
  const MeshRef& mesh() const { return *mesh_; }
  std::shared_ptr<const MeshRef> mesh_ref() const { return mesh_; }
  // The name this session's creator gave its upload (identical files share one MeshRef,
  // which keeps the first uploader's name: never shown to another user). Set once, before
  // the session is published; restore() takes it from the snapshot.
  void name_upload(const std::string& filename);
  // What Session.mesh_name shows: the library name, or this session's own upload name.
  const std::string& mesh_name() const;
  // Runs `task` on this session's strand (serialized, on the worker pool).
  void post(WorkerPool::Task task) { strand_->post(std::move(task)); }
  // Runs `admit` (which may throw; then nothing is posted) and posts `task`, as one step
  // against every other admit_and_post on this session: the strand runs the tasks in the
  // order their admits ran, which coalescing tickets rely on (the newest ticket runs last).
  // RESOURCE_EXHAUSTED naming --max-session-queue when `limit` calls already wait.
  template <class Admit>
  void admit_and_post(Admit&& admit, WorkerPool::Task task, std::size_t limit) {
    std::lock_guard lock(arrival_mutex_);
    check_queue_locked(limit);
    admit();
    strand_->post(std::move(task));
  }

  // ---- blocking: call on the strand. Throw ServiceError / InvalidInput. ----
  // expected_config_version (0: any): ABORTED unless no constraint or β change came since.
  // `client_id`: the author recorded in the history (empty: anonymous).
  // discard_timeline: new constraints may drop keys another client set (else ABORTED).
  pb::Session set_constraints(const pb::Constraints& constraints, std::int64_t expected_version,
                              std::int64_t expected_config_version = 0,
                              const std::string& client_id = "", bool discard_timeline = false);
  pb::Session set_beta(const pb::Beta& beta, std::int64_t expected_version,
                       std::int64_t expected_config_version = 0,
                       const std::string& client_id = "");

  // History and named snapshots (history.h; docs/api.md "History and snapshots"). Each
  // change — saving and deleting a snapshot too — is a new step that every watcher sees; undo
  // and redo are refused (ABORTED) when a later change touched what they would revert.
  pb::Session undo(const pb::UndoRequest& request);  // request.discard_timeline as above
  pb::Session redo(const pb::UndoRequest& request);
  pb::ListHistoryResponse list_history(const pb::ListHistoryRequest& request) const;
  pb::NamedSnapshot save_snapshot(const pb::SaveSnapshotRequest& request);
  pb::ListSnapshotsResponse list_snapshots() const;
  pb::Session restore_snapshot(const pb::RestoreSnapshotRequest& request);
  void delete_snapshot(const std::string& snapshot, const std::string& client_id = "");
  // Durable state: the named snapshots as stored (a fresh session only).
  void adopt_snapshots(const google::protobuf::RepeatedPtrField<pb::NamedSnapshot>& snapshots);

  // Timeline (timeline.h; docs/api.md "Timeline and animation"). set_timeline runs on the
  // strand and is a step: it is checked against the constraint set, which a SetConstraints
  // may replace (that drops the keys as part of its step: their transforms are per handle).
  pb::Timeline set_timeline(const pb::SetTimelineRequest& request);
  pb::Timeline timeline() const;
  pb::Keyframe pose_at(double time_s) const;
  // What sweeps and exports read (session_pose.h; their planners: sweep_plan.h,
  // animation_plan.h, rig_export.h). NOT_FOUND once the session is closed.
  SessionPose pose() const;
  const RequestLimits& limits() const { return limits_; }

  struct Update {
    std::int64_t sequence = 0;
    const google::protobuf::RepeatedPtrField<pb::HandleTransform>* transforms = nullptr;
    bool keep_transforms_if_empty = false;  // Deform: a β-only message
    bool energies = false;
    // More moves follow (DeformRequest.dragging): a drag-path frame (float32 factor, within
    // kDragTolerance of the exact solve), with measures at most every kDragMeasuresPeriod.
    bool dragging = false;
    const pb::Beta* beta = nullptr;  // also change β
    std::int64_t expected_version = 0;
    // Which handles `transforms` are for (empty: all); the others keep their transforms.
    const google::protobuf::RepeatedField<std::int32_t>* handles = nullptr;
    std::string client_id;  // the sender (may move the handles it holds); empty: anonymous
    // UpdateHandles: a positive `sequence` orders client_id's updates. Each one applied is
    // recorded; a coalescing one (`coalesce`) no newer than the client's last applied update
    // is stale: it commits no move (see Move::newer).
    bool sequenced = false;
    bool coalesce = false;
    // The frame returned carries the solve's doubles (FRAME_ENCODING_FLOAT64); observers still
    // get the float32 frame.
    bool float64 = false;
  };
  // Solves, commits the transforms (bumping the version) and sends the frame to every
  // observer. Returns the frame. A stale update (Update::coalesce) moves nothing: it is
  // answered superseded when the session's last frame is current, else it solves the frame
  // of the client's newer update that was committed unsolved (so a drag's last frame comes).
  std::shared_ptr<pb::Frame> update(const Update& update);
  // A coalesced update whose turn came after a newer one: its moves are committed (so a
  // partial update from another editor is never lost) without a solve; answers superseded.
  pb::Frame supersede(const Update& update);
  // The pose a move is about to commit, with the version it will have.
  struct PendingPose {
    const std::vector<HandleTransform>& transforms;
    const SessionBeta& beta;
    std::int64_t version;
    bool beta_changed;
  };
  // The durable store's step of the one commit path (SessionStore): called on the strand
  // with a move about to be committed (`pose`), or with null after any other change was
  // applied and before it is recorded and broadcast. Writes the session's record where the
  // store promises it (every change; a move where each must be durable before it is
  // answered); throws ServiceError UNAVAILABLE to refuse the change, which then changes
  // nothing. The lock it returns is held until the change is committed, so no other write
  // of this session's record comes between. Set before the session is shared.
  using StoreGate = std::function<std::unique_lock<std::mutex>(Session&, const PendingPose* pose)>;
  void set_store_gate(StoreGate gate) { store_gate_ = std::move(gate); }
  // GetMesh's file (its `name` is not read). Throws InvalidInput for an unknown enum value and
  // for a compression the format or the session's upload cannot take.
  std::string mesh_file(const pb::GetMeshRequest& request);
  // `version` (optional): the session version the snapshot shows (read under the same lock).
  pb::Snapshot export_snapshot(bool include_mesh, std::int64_t* version = nullptr) const;
  // Re-applies a snapshot's constraints, β and transforms (a fresh session only).
  void restore(const pb::Snapshot& snapshot);

  // A restored session (durable state): its stored version, tokens and times, after
  // restore(). A fresh session only.
  void adopt(std::int64_t version, const SessionTokens& tokens, std::int64_t create_ms,
             std::int64_t update_ms);
  // The stored history (history_record.h) after adopt(); nullopt: none was stored. One that
  // cannot be read is logged and dropped, and Undo then says why it finds nothing.
  void adopt_history(const std::optional<std::string>& stored);
  // The history in its stored form and the revision it is of (History::revision()).
  std::string history_bytes(std::uint64_t* revision) const;
  std::uint64_t history_revision() const;

  // ---- non-blocking ----
  pb::Session describe() const;

  // Several editors (roster.h): watchers with a client identity, and handle grabs. Each
  // change is sent to every watcher as a presence event. Throw ServiceError.
  // Presence of a watch stream (Roster::join / leave): join returns the claim leave takes.
  Roster::Claim join(const pb::Participant& who, bool editor);
  void leave(const std::string& client_id, Roster::Claim claim);
  pb::GrabHandlesResponse grab(const pb::GrabHandlesRequest& request, bool editor);
  pb::GrabHandlesResponse release(const pb::ReleaseHandlesRequest& request);
  void expire_leases();  // called periodically (SessionStore's sweeper)
  pb::Presence presence() const;
  // Φ_handle in base-GLB order (GetHandleWeights). Throws ServiceError.
  pb::HandleWeights handle_weights(int handle) const;
  // Capability tokens (access.h): what the presented token hashes grant, and new tokens
  // (the old ones stop working at once).
  Access grant(const std::vector<TokenHash>& token_hashes) const;
  IssuedTokens rotate_tokens();
  SessionTokens tokens() const;

  // Bookkeeping of the durable copy (SessionStore): guarded by its own mutex so that saves
  // of one session are ordered and never write an older state over a newer one.
  struct Persisted {
    std::mutex mutex;
    std::int64_t saved_version = -1;    // version of the last record written
    std::int64_t saved_ms = 0;          // when it was written (unix ms)
    std::atomic<bool> dirty{false};     // changed since (coalesced handle moves)
    std::string mesh_key;               // blob key of an uploaded mesh ("" for library)
    std::uint64_t saved_history = 0;    // History::revision() last written (flusher only)
    std::int64_t saved_history_ms = 0;  // when (unix ms)
    std::uint64_t store_generation = 0;  // StateBackend::generation() at the last write
    std::atomic<std::int64_t> checked_ms{0};  // last compared with the store (revalidate)
  };
  Persisted& persisted() { return persisted_; }
  // A WatchSession's sink: it gets the current state, presence and timeline, and everyone
  // else the new observer count; a closed session's sink gets `deleted` and is closed.
  void add_watcher(std::shared_ptr<EventSink> sink);
  void remove_watcher(const EventSink* sink);
  // Who watches and which streams end on revocation (observers.h).
  Observers& observers() { return observers_; }
  const Observers& observers() const { return observers_; }
  // Answers of recent changes by request id (the strand only: every change runs there).
  RequestLog& requests() { return requests_; }
  // Frames as the watchers asked for them, one encode per encoding (encoded_frames.h).
  EncodedFrameCache& encoded_frames() { return encoded_frames_; }
  void touch();
  std::chrono::steady_clock::time_point last_used() const;
  // Pipelined UpdateHandles (UpdateHandlesRequest.coalesce): each such update holds a
  // ticket while it waits for the strand; only the newest ticket's update is solved.
  class CoalesceTicket {
   public:
    CoalesceTicket(Session& s, std::uint64_t id) : session_(s), id_(id) {}
    CoalesceTicket(const CoalesceTicket&) = delete;
    CoalesceTicket& operator=(const CoalesceTicket&) = delete;
    ~CoalesceTicket() { --session_.coalesce_waiting_; }
    // A newer coalescing update arrived after this one: answer superseded, do not solve.
    bool superseded() const { return id_ != session_.coalesce_newest_.load(); }

   private:
    Session& session_;
    const std::uint64_t id_;
  };
  // RESOURCE_EXHAUSTED when `limit` coalescing updates already wait (--max-pending-updates).
  std::unique_ptr<CoalesceTicket> coalesce_ticket(std::size_t limit);
  // The answer to a superseded update: sequence, version, superseded; no buffers.
  pb::Frame superseded_frame(std::int64_t sequence) const;

  // The session was deleted or expired: observers get `deleted` and their streams end.
  void close();
  bool closed() const { return closed_.load(); }

 private:
  void check_queue_locked(std::size_t limit) const;
  void check_version_locked(std::int64_t expected) const;
  void check_config_version_locked(std::int64_t expected) const;
  // The transforms an update leads to, checked (version, grabs); `moved` gets its handles.
  struct Move {
    std::shared_ptr<const ConstraintSet> cs;
    SessionBeta beta;
    std::string key;
    std::vector<HandleTransform> transforms;
    std::vector<int> moved;  // the handles the update changes
    std::int64_t version = 0;  // the session's when the move began (the strand keeps it)
    // Set when the update is stale: the client's newer update, already applied.
    std::optional<ClientSequences::Applied> newer;
  };
  Move begin_move(const Update& u);
  pb::Frame superseded_locked(const Update& u) const;  // the answer of an unsolved update
  std::vector<int> handle_indices(const google::protobuf::RepeatedField<std::int32_t>& handles,
                                  const char* op) const;
  void broadcast_presence();
  void broadcast_step(const pb::HistoryStep& step);
  void broadcast_timeline();
  // A frame of the current state to every watcher (after undo, redo, restore).
  void broadcast_frame(const std::string& client_id);
  // The current state; `snapshot`: with that named snapshot's value (null: none).
  EditState edit_state_locked(const std::string& snapshot = {}) const;
  // The constraint set `given` resolves to, from the cache or built; `key` gets its key.
  std::shared_ptr<const ConstraintSet> constraint_set_of(const pb::Constraints& given,
                                                         std::string* key);
  // A change as a command (docs/architecture.md "One path for a change"): the state it
  // leads to and its step (kind, author, what it touches; history.h).
  struct Change {
    EditState target;
    std::shared_ptr<const ConstraintSet> cs;  // target's set if the caller built it
    Step step;
    bool send_frame = false;        // watchers get the new pose's frame (undo, restore)
    bool discard_timeline = false;  // may drop keys another client set
  };
  // The one commit path of every change but a handle move's (update()): builds what the
  // target needs (its constraint set, the β factorization) and charges it to the cache,
  // checks the change still fits (another client's keys, the snapshot cap), applies it,
  // stores it (StoreGate; a refusal puts everything back), records the step and tells the
  // watchers.
  pb::Session execute(Change change);
  // What execute() puts back when the store refuses a change.
  struct Applied {
    EditState state;
    std::shared_ptr<const ConstraintSet> cs;
    std::int64_t version = 0, config_version = 0, update_ms = 0;
    std::shared_ptr<const hdeform::Frame> last_frame;
    std::int64_t last_frame_version = 0;
  };
  Applied applied_locked(const std::string& snapshot) const;
  // Through store_gate_; when it refuses, puts `applied` back (execute) and rethrows.
  std::unique_lock<std::mutex> store(const PendingPose* pose, Applied* applied = nullptr,
                                     const std::string& snapshot = {});
  void put_back_locked(Applied applied, const std::string& snapshot);
  // The step's bookkeeping (version, time, author, what it touched) and into the history,
  // which may merge it with its predecessor (History::record). Returns it as recorded.
  pb::HistoryStep record_locked(Step step);
  std::string author_of(const std::string& client_id) const;
  void close_drag(const std::string& client_id);  // an open drag becomes its step
  // Undo (undo = true) or Redo: the step's reverse or itself, as a new step.
  pb::Session revert(const pb::UndoRequest& request, bool undo);
  void describe_locked(pb::Session* out) const;
  // A state change under the lock: new version, stale frame dropped, `out` describes it.
  void changed_locked(pb::Session* out);
  void broadcast_state(const EventSink* except = nullptr);
  std::shared_ptr<const ConstraintSet> constraint_set_for(const Constraints& c,
                                                          const std::string& key);
  // Validates a proto β and resolves its local entries (automatic: value not yet picked).
  // keep_automatic_value: a snapshot's automatic β keeps its pick instead of a new one.
  SessionBeta parse_beta(const pb::Beta& beta, bool keep_automatic_value = false) const;
  // Automatic β: runs select_beta at `transforms` and stores the pick in `beta`.
  void pick_beta(SessionBeta& beta, const ConstraintSet& cs,
                 const std::vector<HandleTransform>& transforms);
  // Builds the factorization `beta` needs (for a local field: by one cheap solve).
  void prepare_beta(const ConstraintSet& cs, const SessionBeta& beta);
  // A move's frame, into a frame and buffers the session reuses (no allocation per move).
  std::shared_ptr<hdeform::Frame> solve_move(const ConstraintSet& cs,
                                             const std::vector<HandleTransform>& transforms,
                                             const SessionBeta& beta, const Update& u);
  Vertices deformed_positions();  // current deformation (solves if needed), engine order

  const std::string id_, name_;
  const std::shared_ptr<const MeshRef> mesh_;
  std::string upload_name_;  // name_upload(); empty: a library mesh or not named
  const RequestLimits limits_;
  Cache& cache_;
  std::shared_ptr<Strand> strand_;
  std::mutex arrival_mutex_;  // admit_and_post: ticket order == strand order

  mutable std::mutex mutex_;  // guards everything below
  std::shared_ptr<const ConstraintSet> cs_;
  std::string cs_key_;
  // Constraints as the client gave them (snapshots, history).
  std::shared_ptr<const pb::Constraints> given_;
  History history_;
  std::map<std::string, std::shared_ptr<const pb::NamedSnapshot>> snapshots_;  // by name
  // As set (checked against cs_), with version and author; shared with history steps.
  std::shared_ptr<const pb::Timeline> timeline_ = std::make_shared<const pb::Timeline>();
  SessionBeta beta_;
  std::vector<HandleTransform> transforms_;
  std::int64_t version_ = 1;
  std::int64_t config_version_ = 1;  // bumped by constraint and β changes only

 public:
  std::int64_t version() const {
    std::lock_guard lock(mutex_);
    return version_;
  }

 private:
  std::shared_ptr<const hdeform::Frame> last_frame_;  // engine frame at last_frame_version_
  std::int64_t last_frame_version_ = 0;

  // The buffers of this session's moves (guarded by move_mutex_; never take mutex_ under it): a
  // move reuses the workspace and the frame before the last one once nobody holds it.
  std::mutex move_mutex_;
  hdeform::UpdateWorkspace workspace_;
  std::shared_ptr<hdeform::Frame> spare_frame_;
  std::chrono::steady_clock::time_point last_measured_{};
  std::int64_t create_ms_ = 0, update_ms_ = 0;
  SessionTokens tokens_;
  Persisted persisted_;
  StoreGate store_gate_;  // empty: not durable
  Roster roster_;
  ClientSequences sequences_;  // guarded by mutex_
  EncodedFrameCache encoded_frames_;
  RequestLog requests_;  // the strand only
  Observers observers_;

  std::atomic<std::size_t> coalesce_waiting_{0};
  std::atomic<std::uint64_t> coalesce_newest_{0};
  std::atomic<bool> closed_{false};
  std::atomic<std::int64_t> last_used_ns_{0};
};

std::int64_t unix_ms_now();

// Whether a snapshot's restore builds a constraint set (and so factors at once).
bool snapshot_has_constraints(const pb::Snapshot& snapshot);

}  // namespace hdeform::service
