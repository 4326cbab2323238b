// Load bench: many sessions, each with live editors and watchers, for minutes.
// How to run and the measured numbers: docs/benchmarks.md, "Load".
//
// A timed soak rather than a Google Benchmark fixture: what matters is what happens over
// minutes (errors, the server's memory curve, latency under sustained load), not the mean
// of many short iterations.
//
//   * The server is a separate process: by default this program spawns hdeform-server
//     (--port 0) and reads "listening on HOST:PORT" from its stdout, so that the server's
//     VmRSS can be sampled from /proc/PID/status once a second without the bench's own
//     allocations in it. --server HOST:PORT targets a running server instead (RSS only with
//     --server-pid).
//   * --sessions library sessions, cycling through --meshes. A mesh with a Botsch–Sorkine
//     .sel beside it is constrained with it (label 0 fixed, label 2 handle, as the service
//     tests do); any other mesh with two half-spaces across its longest bounding-box axis.
//     --capsule N instead uploads the procedural capsule of about N vertices (tests/fixtures/
//     procedural.h, as engine_bench and service_bench use) to every session: base fixed, cap
//     handle; the capacity curve (docs/benchmarks.md "Capacity") is measured on it.
//   * Per session, --editors Deform streams, each sending one update every 1/--rate s (a
//     smooth sinusoidal rotation + translation of the handle; the editors of a session are
//     out of phase, so they really pull against each other), and --watchers WatchSession
//     streams. --drag marks every update `dragging`, as the viewer does mid-drag (the drag
//     path's frames, and the server keeps its cores warm between them).
//   * All streams use gRPC's callback API, so the whole client runs on gRPC's own small
//     thread pool plus one driver thread that paces the updates and the main thread that
//     samples and prints.
//
// Latency. Deform is latest-wins: the server drops updates that were superseded while a
// solve ran, and each Frame.sequence names the update it answers. Two figures:
//   per frame   receive time of a frame − send time of the update it answers (its own
//               sequence): how stale a frame is when the user sees it;
//   per update  send time of update s → the first frame with sequence ≥ s on that stream:
//               how long a user's move waits to show, coalesced updates included.
//
// Errors: any non-OK final status (other than a cancellation that the bench itself makes at
// the end), a failed write, a malformed or out-of-order frame, a `deleted` event before the
// bench deletes the sessions, a failed DeleteSession. The exit status is 1 when there is one.
#include "hdeform/v1/deform.grpc.pb.h"
#include "engine/io/mesh_io.h"
#include "capsule_upload.h"

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>

#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <queue>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#ifndef HDEFORM_LOAD_DATA
#define HDEFORM_LOAD_DATA "data"
#endif

namespace {

namespace pb = ::hdeform::v1;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}
double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Nearest-rank percentile (q in (0, 1]) of a sorted vector.
double percentile_sorted(const std::vector<float>& v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

std::string loadavg() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  f >> a >> b >> c;
  return a + " " + b + " " + c;
}

// ---------------------------------------------------------------------------------------
// /proc sampling of the server process.

// VmRSS of PID in MiB; negative when unknown (no pid, process gone).
double rss_mib(pid_t pid) {
  if (pid <= 0) return -1;
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

// User + system CPU seconds of PID; negative when unknown.
double cpu_seconds(pid_t pid) {
  if (pid <= 0) return -1;
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string all((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  // The command name (field 2) may contain spaces: count fields after its closing ')'.
  const auto close = all.rfind(')');
  if (close == std::string::npos) return -1;
  std::istringstream rest(all.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

double own_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// ---------------------------------------------------------------------------------------
// A spawned hdeform-server. Its stdout (the log) must be drained for the whole run: a full
// pipe would block the server's logging threads and show up as latency.
class ChildServer {
 public:
  ChildServer(const std::string& binary, const std::vector<std::string>& args) {
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGTERM);  // never leave a server behind if the bench dies
      dup2(fds[1], STDOUT_FILENO);
      close(fds[0]);
      close(fds[1]);
      std::vector<char*> argv;
      argv.push_back(const_cast<char*>(binary.c_str()));
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(binary.c_str(), argv.data());
      std::perror(("exec " + binary).c_str());
      _exit(127);
    }
    close(fds[1]);
    fd_ = fds[0];
    const std::string marker = "listening on ";
    const auto deadline = Clock::now() + std::chrono::seconds(30);
    std::string line;
    while (read_line(line, deadline)) {
      std::cerr << "[server] " << line << "\n";
      if (const auto at = line.find(marker); at != std::string::npos) {
        address_ = line.substr(at + marker.size());
        while (!address_.empty() && std::isspace(static_cast<unsigned char>(address_.back())))
          address_.pop_back();
        break;
      }
    }
    if (address_.empty()) {
      stop();
      throw std::runtime_error("hdeform-server did not print 'listening on HOST:PORT' within 30 s");
    }
    drain_ = std::thread([this] {
      std::string l;
      while (read_line(l, Clock::time_point::max())) {
        ++log_lines_;
        std::cerr << "[server] " << l << "\n";
      }
    });
  }
  ~ChildServer() { stop(); }
  ChildServer(const ChildServer&) = delete;
  ChildServer& operator=(const ChildServer&) = delete;

  pid_t pid() const { return pid_; }
  const std::string& address() const { return address_; }
  long log_lines() const { return log_lines_; }

  // SIGTERM, then wait up to 10 s (the server promises to exit within 5 s). Returns a
  // description of how it ended.
  std::string stop() {
    if (pid_ <= 0) return "already stopped";
    const auto t0 = Clock::now();
    kill(pid_, SIGTERM);
    int status = 0;
    bool exited = false;
    while (Clock::now() - t0 < std::chrono::seconds(10)) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited = true;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::ostringstream out;
    if (!exited) {
      kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
      out << "did not exit within 10 s of SIGTERM: killed";
    } else if (WIFEXITED(status)) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.2f", seconds_between(t0, Clock::now()));
      out << "exit code " << WEXITSTATUS(status) << " " << buf << " s after SIGTERM";
    } else if (WIFSIGNALED(status)) {
      out << "killed by signal " << WTERMSIG(status);
    }
    pid_ = -1;
    if (drain_.joinable()) drain_.join();  // EOF once the server is gone
    if (fd_ >= 0) close(fd_);
    fd_ = -1;
    return out.str();
  }

 private:
  // One line from the pipe; false on EOF or when the deadline passes.
  bool read_line(std::string& line, Clock::time_point deadline) {
    for (;;) {
      if (const auto nl = buffer_.find('\n'); nl != std::string::npos) {
        line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return true;
      }
      int timeout_ms = -1;
      if (deadline != Clock::time_point::max()) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - Clock::now());
        if (left.count() <= 0) return false;
        timeout_ms = static_cast<int>(left.count());
      }
      pollfd p{fd_, POLLIN, 0};
      const int r = poll(&p, 1, timeout_ms);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) return false;
      char chunk[4096];
      const ssize_t n = read(fd_, chunk, sizeof chunk);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        if (buffer_.empty()) return false;
        line.swap(buffer_);
        buffer_.clear();
        return true;
      }
      buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }

  pid_t pid_ = -1;
  int fd_ = -1;
  std::string address_;
  std::string buffer_;
  std::thread drain_;
  std::atomic<long> log_lines_{0};
};

// ---------------------------------------------------------------------------------------
// Counters and errors shared by all streams.
struct Shared {
  bool drag = false;  // --drag: every update marked `dragging` (drag-precision frames)
  std::atomic<bool> stopping{false};  // from now on `deleted` and our cancellations are expected
  std::atomic<std::int64_t> updates_sent{0}, editor_frames{0}, watcher_frames{0},
      watcher_states{0}, watcher_other{0}, client_coalesced{0};

  // Error messages with their counts (streams report from gRPC threads).
  std::mutex error_mu;
  std::map<std::string, std::int64_t> errors;
  std::atomic<std::int64_t> error_count{0};
  void error(const std::string& what) {
    ++error_count;
    std::lock_guard lock(error_mu);
    ++errors[what];
  }

  // Streams that have finished (OnDone), and watchers that have seen their first state.
  std::mutex mu;
  std::condition_variable cv;
  int editors_done = 0, watchers_done = 0, watchers_ready = 0;
  void bump(int& counter) {
    {
      std::lock_guard lock(mu);
      ++counter;
    }
    cv.notify_all();
  }
  bool wait_for(int& counter, int target, std::chrono::seconds timeout) {
    std::unique_lock lock(mu);
    return cv.wait_for(lock, timeout, [&] { return counter >= target; });
  }
};

std::string status_text(const grpc::Status& s) {
  static const char* const names[] = {
      "OK",        "CANCELLED",          "UNKNOWN",   "INVALID_ARGUMENT", "DEADLINE_EXCEEDED",
      "NOT_FOUND", "ALREADY_EXISTS",     "PERMISSION_DENIED", "RESOURCE_EXHAUSTED",
      "FAILED_PRECONDITION", "ABORTED",  "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL",
      "UNAVAILABLE", "DATA_LOSS",        "UNAUTHENTICATED"};
  const int code = static_cast<int>(s.error_code());
  const std::string name = code >= 0 && code <= 16 ? names[code] : std::to_string(code);
  return name + (s.error_message().empty() ? "" : ": " + s.error_message());
}

// One session of the run and how its handle moves.
struct SessionPlan {
  std::string mesh, name;
  std::string edit_token;            // CreateSession's answer: presented on every call
  int vertex_count = 0;
  int long_axis = 2, side_axis = 0;  // bounding-box axes: along the shape, across it
  double extent = 1;                 // bounding-box length along long_axis
  std::string constraints;           // "sel" or "half-space", for the report
};

// ---------------------------------------------------------------------------------------
// One live editor: a Deform stream. Updates are started by the driver thread (outside any
// reaction), so a hold keeps OnDone back until close(); gRPC allows one write in flight, so
// an update that comes while one is in flight waits in `pending_` and a newer one replaces
// it (client-side latest wins, counted; it only happens when the transport pushes back).
class Editor final : public grpc::ClientBidiReactor<pb::DeformRequest, pb::Frame> {
 public:
  Editor(const SessionPlan& plan, int index, Shared& shared)
      : plan_(plan), index_(index), shared_(shared) {}

  void start(pb::Deformation::Stub& stub) {
    ctx_.AddMetadata("authorization", "Bearer " + plan_.edit_token);
    stub.async()->Deform(&ctx_, this);
    AddHold();
    StartRead(&frame_);
    StartCall();
  }

  // Driver thread: the update for time t (seconds since the start of streaming).
  void send(double t) {
    bool start = false;
    {
      std::lock_guard lock(mu_);
      if (closing_) return;
      ++seq_;
      if (in_flight_) {
        if (has_pending_) ++shared_.client_coalesced;
        fill(pending_, seq_, t);
        has_pending_ = true;
        return;
      }
      fill(write_, seq_, t);
      sent_.push_back({seq_, Clock::now()});
      in_flight_ = start = true;
    }
    if (start) {
      ++shared_.updates_sent;
      ++updates_;
      StartWrite(&write_);
    }
  }

  // Driver/main thread: no more updates; the server answers the newest and ends with OK.
  void close() {
    bool writes_done = false;
    {
      std::lock_guard lock(mu_);
      closing_ = true;
      if (!in_flight_) in_flight_ = writes_done = true;
    }
    if (writes_done) StartWritesDone();
    RemoveHold();
  }

  void cancel() { ctx_.TryCancel(); }

  void OnWriteDone(bool ok) override {
    bool next = false, writes_done = false;
    {
      std::lock_guard lock(mu_);
      if (!ok) {
        // The stream is broken; OnDone will carry the status. Stop sending.
        if (!closing_) shared_.error(label() + ": write failed (stream broken)");
        closing_ = true;
        return;  // in_flight_ stays set: nothing more is written
      }
      if (has_pending_) {
        write_.Swap(&pending_);
        has_pending_ = false;
        sent_.push_back({write_.sequence(), Clock::now()});
        next = true;
      } else if (closing_) {
        writes_done = true;
      } else {
        in_flight_ = false;
      }
    }
    if (next) {
      ++shared_.updates_sent;
      ++updates_;
      StartWrite(&write_);
    }
    if (writes_done) StartWritesDone();
  }

  void OnReadDone(bool ok) override {
    if (!ok) return;  // the server ended the stream; OnDone follows
    const auto now = Clock::now();
    const std::size_t expected = 12u * static_cast<std::size_t>(plan_.vertex_count);
    if (frame_.positions().size() != expected || frame_.normals().size() != expected)
      shared_.error(label() + ": frame buffers of the wrong size");
    ++shared_.editor_frames;
    {
      std::lock_guard lock(mu_);
      ++frames_;
      const std::int64_t s = frame_.sequence();
      if (s <= last_seq_) {
        shared_.error(label() + ": frame sequence did not increase");
      } else {
        last_seq_ = s;
        // Every update still waiting with sequence ≤ s is answered by this frame.
        bool own = false;
        while (!sent_.empty() && sent_.front().seq <= s) {
          update_lat_.push_back(static_cast<float>(ms_between(sent_.front().at, now)));
          if (sent_.front().seq == s) {
            frame_lat_.push_back(update_lat_.back());
            own = true;
          }
          sent_.pop_front();
        }
        if (!own) shared_.error(label() + ": frame answers an update never sent");
      }
    }
    StartRead(&frame_);
  }

  void OnDone(const grpc::Status& status) override {
    {
      std::lock_guard lock(mu_);
      status_ = status;
      // Latest wins, but the newest update is always answered: nothing may be left waiting.
      unanswered_ = static_cast<std::int64_t>(sent_.size());
    }
    if (!status.ok() && !(cancelled_by_us_ && status.error_code() == grpc::StatusCode::CANCELLED))
      shared_.error(label() + ": Deform ended with " + status_text(status));
    if (status.ok() && unanswered_ > 0)
      shared_.error(label() + ": stream ended OK with updates unanswered");
    shared_.bump(shared_.editors_done);
  }

  // Main thread, between reports: the per-frame latencies recorded since the last call.
  void take_recent(std::vector<float>& out) {
    std::lock_guard lock(mu_);
    out.insert(out.end(), frame_lat_.begin() + static_cast<std::ptrdiff_t>(reported_),
               frame_lat_.end());
    reported_ = frame_lat_.size();
  }

  // Only after OnDone.
  const std::vector<float>& frame_latencies() const { return frame_lat_; }
  const std::vector<float>& update_latencies() const { return update_lat_; }
  std::int64_t unanswered() const { return unanswered_; }
  bool newest_answered() const { return status_.ok() && unanswered_ == 0 && last_seq_ == seq_; }
  void mark_cancelled() { cancelled_by_us_ = true; }

 private:
  struct Sent {
    std::int64_t seq;
    Clock::time_point at;
  };

  std::string label() const { return plan_.name + " editor " + std::to_string(index_); }

  // The handle moves on a slow sinusoid (0.5 Hz): rotation about the axis across the shape
  // and a sideways translation, each editor a quarter period behind the previous one.
  void fill(pb::DeformRequest& r, std::int64_t seq, double t) const {
    constexpr double kHz = 0.5, kMaxAngle = 25.0 * std::numbers::pi / 180.0, kShift = 0.1;
    r.Clear();
    if (seq == 1) r.set_name(plan_.name);  // the first message names the session
    r.set_sequence(seq);
    r.set_dragging(shared_.drag);
    const double phase = 2 * std::numbers::pi * kHz * t + index_ * std::numbers::pi / 2;
    const double angle = kMaxAngle * std::sin(phase);
    auto* tr = r.add_transforms();
    auto* q = tr->mutable_rotation();
    const std::array<double, 3> axis{plan_.side_axis == 0 ? 1.0 : 0.0,
                                     plan_.side_axis == 1 ? 1.0 : 0.0,
                                     plan_.side_axis == 2 ? 1.0 : 0.0};
    q->set_w(std::cos(angle / 2));
    q->set_x(axis[0] * std::sin(angle / 2));
    q->set_y(axis[1] * std::sin(angle / 2));
    q->set_z(axis[2] * std::sin(angle / 2));
    const double shift = kShift * plan_.extent * std::sin(phase);
    // Sideways: along the third axis (neither along the shape nor the rotation axis).
    const int across = 3 - plan_.long_axis - plan_.side_axis;
    auto* v = tr->mutable_translation();
    if (across == 0) v->set_x(shift);
    if (across == 1) v->set_y(shift);
    if (across == 2) v->set_z(shift);
  }

  const SessionPlan& plan_;
  const int index_;
  Shared& shared_;
  grpc::ClientContext ctx_;
  pb::Frame frame_;  // the read buffer

  std::mutex mu_;
  pb::DeformRequest write_, pending_;  // the write in flight; the next one waiting
  bool in_flight_ = false, has_pending_ = false, closing_ = false;
  std::int64_t seq_ = 0, last_seq_ = 0, updates_ = 0, frames_ = 0;
  std::deque<Sent> sent_;  // updates sent and not answered yet, in sequence order
  std::vector<float> frame_lat_, update_lat_;  // ms
  std::size_t reported_ = 0;
  grpc::Status status_;
  std::int64_t unanswered_ = 0;
  std::atomic<bool> cancelled_by_us_{false};
};

// ---------------------------------------------------------------------------------------
// One observer: a WatchSession stream. It only counts; every event is checked for shape.
class Watcher final : public grpc::ClientReadReactor<pb::SessionEvent> {
 public:
  Watcher(const SessionPlan& plan, int index, Shared& shared)
      : plan_(plan), index_(index), shared_(shared) {}

  void start(pb::Deformation::Stub& stub) {
    request_.set_name(plan_.name);
    ctx_.AddMetadata("authorization", "Bearer " + plan_.edit_token);
    stub.async()->WatchSession(&ctx_, &request_, this);
    StartRead(&event_);
    StartCall();
  }

  void cancel() {
    cancelled_by_us_ = true;
    ctx_.TryCancel();
  }

  void OnReadDone(bool ok) override {
    if (!ok) return;
    switch (event_.event_case()) {
      case pb::SessionEvent::kFrame: {
        const std::size_t expected = 12u * static_cast<std::size_t>(plan_.vertex_count);
        if (event_.frame().positions().size() != expected)
          shared_.error(label() + ": frame buffers of the wrong size");
        ++frames_;
        ++shared_.watcher_frames;
        break;
      }
      case pb::SessionEvent::kState:
        ++shared_.watcher_states;
        if (states_++ == 0) shared_.bump(shared_.watchers_ready);
        break;
      case pb::SessionEvent::kDeleted:
        saw_deleted_ = true;
        if (!shared_.stopping) shared_.error(label() + ": session deleted during the run");
        break;
      case pb::SessionEvent::kPresence:
      case pb::SessionEvent::kStep:
      case pb::SessionEvent::kTimeline:
        ++shared_.watcher_other;  // who is here, history steps, keys: counted, not errors
        break;
      case pb::SessionEvent::EVENT_NOT_SET:
        shared_.error(label() + ": empty SessionEvent");
    }
    StartRead(&event_);
  }

  void OnDone(const grpc::Status& status) override {
    if (cancelled_by_us_ && status.error_code() == grpc::StatusCode::CANCELLED)
      cancelled_at_end_ = true;
    else if (!status.ok())
      shared_.error(label() + ": WatchSession ended with " + status_text(status));
    shared_.bump(shared_.watchers_done);
  }

  std::int64_t frames() const { return frames_; }
  bool saw_deleted() const { return saw_deleted_; }
  bool cancelled_at_end() const { return cancelled_at_end_; }

 private:
  std::string label() const { return plan_.name + " watcher " + std::to_string(index_); }

  const SessionPlan& plan_;
  const int index_;
  Shared& shared_;
  grpc::ClientContext ctx_;
  pb::WatchSessionRequest request_;
  pb::SessionEvent event_;
  std::atomic<std::int64_t> frames_{0};
  std::int64_t states_ = 0;  // reactions of one stream never overlap
  std::atomic<bool> saw_deleted_{false}, cancelled_by_us_{false}, cancelled_at_end_{false};
};

// ---------------------------------------------------------------------------------------
// Session set-up (blocking stub calls; done once before the clock starts).

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return {};
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double coord(const pb::Vec3& v, int axis) { return axis == 0 ? v.x() : axis == 1 ? v.y() : v.z(); }

pb::Vec3 unit(int axis, double sign) {
  pb::Vec3 v;
  if (axis == 0) v.set_x(sign);
  if (axis == 1) v.set_y(sign);
  if (axis == 2) v.set_z(sign);
  return v;
}

// The constraints of MESH: its .sel file when the library has one (fixed = label 0, handle =
// label 2), else the bottom and top 12 % along the longest bounding-box axis (half-spaces).
pb::Constraints constraints_for(const pb::LibraryMesh& mesh, const pb::Session& s,
                                const fs::path& data_dir, SessionPlan& plan) {
  pb::Constraints c;
  if (mesh.has_benchmark()) {
    const fs::path sel = (data_dir / mesh.path()).replace_extension(".sel");
    const std::string bytes = slurp(sel);
    if (!bytes.empty()) {
      for (int label : {0, 2}) {
        auto* region = label == 0 ? c.mutable_fixed() : c.add_handles();
        auto* selector = region->add_selectors()->mutable_sel();
        selector->set_content(bytes);
        selector->set_label(label);
      }
      plan.constraints = "sel";
      return c;
    }
    std::cerr << "note: " << sel << " not readable; half-spaces for " << mesh.name() << "\n";
  }
  const int a = plan.long_axis;
  const double lo = coord(s.bbox_min(), a), hi = coord(s.bbox_max(), a);
  auto* fixed = c.mutable_fixed()->add_selectors()->mutable_half_space();
  *fixed->mutable_normal() = unit(a, -1);  // dot(n, x) ≥ offset: x_a ≤ lo + 12 %
  fixed->set_offset(-(lo + 0.12 * (hi - lo)));
  auto* handle = c.add_handles()->add_selectors()->mutable_half_space();
  *handle->mutable_normal() = unit(a, 1);
  handle->set_offset(hi - 0.12 * (hi - lo));
  plan.constraints = "half-space";
  return c;
}

// `token`: the session's edit token (empty for calls that name no session).
template <class Call>
grpc::Status with_deadline(Call&& call, const std::string& token = "", int seconds = 120) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(seconds));
  if (!token.empty()) ctx.AddMetadata("authorization", "Bearer " + token);
  return call(ctx);
}

// The plan of a session CreateSession just answered: its name, token and bounding-box axes.
SessionPlan plan_of(const std::string& mesh, const pb::Session& s) {
  SessionPlan plan;
  plan.mesh = mesh;
  plan.name = s.name();
  plan.edit_token = s.edit_token();
  plan.vertex_count = s.vertex_count();
  std::array<double, 3> size{};
  for (int k = 0; k < 3; ++k) size[k] = coord(s.bbox_max(), k) - coord(s.bbox_min(), k);
  plan.long_axis = static_cast<int>(std::max_element(size.begin(), size.end()) - size.begin());
  plan.side_axis = (plan.long_axis + 1) % 3;
  plan.extent = size[plan.long_axis];
  return plan;
}

bool set_constraints(pb::Deformation::Stub& stub, const SessionPlan& plan,
                     const pb::Constraints& constraints, std::string& error) {
  pb::SetConstraintsRequest req;
  req.set_name(plan.name);
  *req.mutable_constraints() = constraints;
  pb::Session out;
  const auto status = with_deadline(
      [&](grpc::ClientContext& ctx) { return stub.SetConstraints(&ctx, req, &out); },
      plan.edit_token);
  if (!status.ok())
    error = "SetConstraints " + plan.name + " (" + plan.mesh + "): " + status_text(status);
  return status.ok();
}

std::optional<SessionPlan> open_session(pb::Deformation::Stub& stub, const pb::LibraryMesh& mesh,
                                        const fs::path& data_dir, std::string& error) {
  pb::Session s;
  auto status = with_deadline([&](grpc::ClientContext& ctx) {
    auto writer = stub.CreateSession(&ctx, &s);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_library_mesh(mesh.name());
    writer->Write(req);
    writer->WritesDone();
    return writer->Finish();
  });
  if (!status.ok()) {
    error = "CreateSession " + mesh.name() + ": " + status_text(status);
    return std::nullopt;
  }
  SessionPlan plan = plan_of(mesh.name(), s);
  if (!set_constraints(stub, plan, constraints_for(mesh, s, data_dir, plan), error))
    return std::nullopt;
  return plan;
}

// The procedural capsule, uploaded as binary PLY (1 MiB chunks) and constrained by ids.
struct Capsule {
  hdeform::procedural::CapsuleCase mesh;
  std::string ply;
};

std::optional<SessionPlan> open_capsule_session(pb::Deformation::Stub& stub, const Capsule& c,
                                                std::string& error) {
  const std::string name = "capsule" + std::to_string(c.mesh.mesh.num_vertices());
  pb::Session s;
  auto status = with_deadline([&](grpc::ClientContext& ctx) {
    return hdeform::bench::upload_mesh(stub, ctx, name + ".ply", c.ply, &s);
  });
  if (!status.ok()) {
    error = "CreateSession " + name + ": " + status_text(status);
    return std::nullopt;
  }
  SessionPlan plan = plan_of(name, s);
  plan.constraints = "base and cap";
  const pb::Constraints constraints = hdeform::bench::capsule_constraints(c.mesh);
  if (!set_constraints(stub, plan, constraints, error)) return std::nullopt;
  return plan;
}

// Least-squares slope of y over x.
double slope(const std::vector<std::pair<double, double>>& xy) {
  if (xy.size() < 2) return 0;
  double mx = 0, my = 0;
  for (const auto& [x, y] : xy) mx += x, my += y;
  mx /= static_cast<double>(xy.size());
  my /= static_cast<double>(xy.size());
  double sxy = 0, sxx = 0;
  for (const auto& [x, y] : xy) sxy += (x - mx) * (y - my), sxx += (x - mx) * (x - mx);
  return sxx > 0 ? sxy / sxx : 0;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(s);
  while (std::getline(in, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

// The hdeform-server of the same build tree: BUILD/bench/load_bench → BUILD/server/.
std::string default_server_binary() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path sibling = self.parent_path().parent_path() / "server" / "hdeform-server";
    if (fs::exists(sibling)) return sibling.string();
  }
  return "build/server/hdeform-server";
}

struct Sample {
  double t, rss;
  std::int64_t updates, editor_frames, watcher_frames;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hdeform load bench: sessions × (editors on Deform + watchers on WatchSession)"};
  std::string server, server_bin = default_server_binary(), server_args, meshes_arg =
      "cactus,bar,cylinder,knight";
  std::string data_dir = HDEFORM_LOAD_DATA, curve_csv;
  int sessions = 100, editors = 2, watchers = 2, channels = 0, report_every = 10, capsule = 0;
  pid_t server_pid = 0;
  double rate = 30, duration = 600;
  app.add_option("--server", server, "HOST:PORT of a running hdeform-server (default: spawn one)");
  app.add_option("--server-bin", server_bin, "hdeform-server to spawn")->capture_default_str();
  app.add_option("--server-args", server_args,
                 "extra arguments for the spawned server (space-separated, e.g. '--workers 2')");
  app.add_option("--server-pid", server_pid, "with --server: its PID, to sample its RSS");
  app.add_option("--sessions", sessions, "sessions")->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--editors", editors, "Deform clients per session")->capture_default_str()->check(CLI::Range(0, 1000));
  app.add_option("--watchers", watchers, "WatchSession clients per session")->capture_default_str()->check(CLI::Range(0, 1000));
  app.add_option("--rate", rate, "updates per second per editor")->capture_default_str()->check(CLI::Range(0.1, 1000.0));
  bool drag = false;
  app.add_flag("--drag", drag, "mark every update `dragging`, as the viewer does mid-drag");
  app.add_option("--duration", duration, "seconds of streaming")->capture_default_str()->check(CLI::Range(1.0, 1e6));
  app.add_option("--meshes", meshes_arg, "library meshes, cycled over the sessions")->capture_default_str();
  app.add_option("--capsule", capsule,
                 "upload the procedural capsule of about this many vertices to every session "
                 "instead of library meshes (0: library meshes)")
      ->capture_default_str()
      ->check(CLI::Range(0, 2000000));
  app.add_option("--data-dir", data_dir, "where the library's .sel files are read from")->capture_default_str();
  app.add_option("--channels", channels, "TCP connections (0 = one per session)")->capture_default_str();
  app.add_option("--report-every", report_every, "seconds between progress lines")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--curve-csv", curve_csv, "write the 1-s samples (t, RSS MiB, counters) here");
  CLI11_PARSE(app, argc, argv);

  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  std::cout << "load_bench: " << command << "\nload average at start: " << loadavg() << "\n";

  // --- the server -------------------------------------------------------------------------
  std::unique_ptr<ChildServer> child;
  std::string address = server;
  pid_t pid = server_pid;
  if (server.empty()) {
    // The default --max-sessions (64) is below a 100-session run; our flags come first so
    // --server-args can override them.
    std::vector<std::string> args{"--port", "0", "--no-state", "--max-sessions",
                                  std::to_string(std::max(64, sessions + 8)), "--log-level",
                                  "warn"};
    for (auto& a : split(server_args, ' ')) args.push_back(a);
    std::cout << "spawning " << server_bin;
    for (const auto& a : args) std::cout << " " << a;
    std::cout << std::endl;
    try {
      child = std::make_unique<ChildServer>(server_bin, args);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
      return 2;
    }
    address = child->address();
    pid = child->pid();
    std::cout << "server PID " << pid << " on " << address << std::endl;
  }

  const int nchannels = std::max(1, channels > 0 ? std::min(channels, sessions) : sessions);
  std::vector<std::shared_ptr<grpc::Channel>> chans;
  std::vector<std::unique_ptr<pb::Deformation::Stub>> stubs;
  for (int i = 0; i < nchannels; ++i) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    args.SetMaxSendMessageSize(-1);
    // Without this, channels with equal arguments share one TCP connection; we want one
    // connection per simulated user group, as real remote users would have.
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
    chans.push_back(grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args));
    stubs.push_back(pb::Deformation::NewStub(chans.back()));
  }
  if (!chans[0]->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10))) {
    std::cerr << "error: cannot connect to " << address << "\n";
    return 2;
  }

  // --- sessions ---------------------------------------------------------------------------
  pb::ListMeshesResponse library;
  {
    auto st = with_deadline([&](grpc::ClientContext& ctx) {
      return stubs[0]->ListMeshes(&ctx, pb::ListMeshesRequest{}, &library);
    });
    if (!st.ok()) {
      std::cerr << "error: ListMeshes: " << status_text(st) << "\n";
      return 2;
    }
  }
  std::vector<pb::LibraryMesh> meshes;
  for (const auto& want : capsule ? std::vector<std::string>{} : split(meshes_arg, ',')) {
    auto it = std::find_if(library.meshes().begin(), library.meshes().end(),
                           [&](const pb::LibraryMesh& m) { return m.name() == want; });
    if (it == library.meshes().end()) {
      std::cerr << "error: mesh '" << want << "' is not in the server's library\n";
      return 2;
    }
    meshes.push_back(*it);
  }
  std::optional<Capsule> capsule_mesh;
  if (capsule) {
    capsule_mesh.emplace();
    capsule_mesh->mesh = hdeform::procedural::capsule_case(capsule);
    hdeform::WriteOptions binary;
    binary.binary_ply = true;
    capsule_mesh->ply = hdeform::write_mesh_bytes(hdeform::MeshFileFormat::ply,
                                                  capsule_mesh->mesh.mesh.V,
                                                  capsule_mesh->mesh.mesh.F, nullptr, binary);
  }

  const double rss_idle = rss_mib(pid);
  const auto setup0 = Clock::now();
  std::vector<SessionPlan> plans;
  plans.reserve(static_cast<std::size_t>(sessions));  // editors keep references into it
  for (int i = 0; i < sessions; ++i) {
    std::string error;
    auto& stub = *stubs[static_cast<std::size_t>(i % nchannels)];
    auto plan = capsule_mesh
                    ? open_capsule_session(stub, *capsule_mesh, error)
                    : open_session(stub, meshes[static_cast<std::size_t>(i) % meshes.size()],
                                   fs::path(data_dir), error);
    if (!plan) {
      std::cerr << "error: " << error << "\n";
      return 2;
    }
    plans.push_back(std::move(*plan));
  }
  const double setup_s = seconds_between(setup0, Clock::now());
  const double rss_setup = rss_mib(pid);
  {
    std::map<std::string, int> per_mesh;
    for (const auto& p : plans)
      ++per_mesh[p.mesh + " (" + std::to_string(p.vertex_count) + " vertices, " +
                 p.constraints + ")"];
    std::printf("%d sessions opened in %.2f s:", sessions, setup_s);
    for (const auto& [m, count] : per_mesh) std::printf(" %d× %s;", count, m.c_str());
    std::printf("\n");
  }

  // --- streams ----------------------------------------------------------------------------
  Shared shared;
  shared.drag = drag;
  std::vector<std::unique_ptr<Watcher>> watch;
  std::vector<std::unique_ptr<Editor>> edit;
  for (int i = 0; i < sessions; ++i) {
    auto& stub = *stubs[static_cast<std::size_t>(i % nchannels)];
    for (int w = 0; w < watchers; ++w) {
      watch.push_back(std::make_unique<Watcher>(plans[static_cast<std::size_t>(i)], w, shared));
      watch.back()->start(stub);
    }
  }
  // Watchers first, each confirmed by its first `state` event, so they see every frame.
  if (!shared.wait_for(shared.watchers_ready, static_cast<int>(watch.size()),
                       std::chrono::seconds(60)))
    shared.error("not every watcher received its first state within 60 s");
  for (int i = 0; i < sessions; ++i) {
    auto& stub = *stubs[static_cast<std::size_t>(i % nchannels)];
    for (int e = 0; e < editors; ++e) {
      edit.push_back(std::make_unique<Editor>(plans[static_cast<std::size_t>(i)], e, shared));
      edit.back()->start(stub);
    }
  }

  // The driver: every editor sends at `rate`, the editors' ticks spread evenly over one
  // period so the server sees a steady stream rather than synchronized bursts. A tick that
  // comes more than a period late (this thread starved of CPU) is skipped, not made up in a
  // burst, and counted: the achieved rate is reported next to the target.
  const auto t0 = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / rate));
  const auto end = t0 + std::chrono::duration_cast<Clock::duration>(
                            std::chrono::duration<double>(duration));
  std::atomic<bool> stop_driver{false};
  std::atomic<std::int64_t> skipped_ticks{0};
  std::thread driver([&] {
    using Tick = std::pair<Clock::time_point, std::size_t>;
    std::priority_queue<Tick, std::vector<Tick>, std::greater<>> ticks;
    for (std::size_t k = 0; k < edit.size(); ++k)
      ticks.push({t0 + period * static_cast<long>(k) / static_cast<long>(edit.size()), k});
    while (!stop_driver && !ticks.empty()) {
      auto [at, k] = ticks.top();
      if (at >= end) break;
      std::this_thread::sleep_until(at);
      ticks.pop();
      const auto now = Clock::now();
      edit[k]->send(seconds_between(t0, now));
      at += period;
      if (now - at > period) {
        ++skipped_ticks;
        at = now + period;
      }
      ticks.push({at, k});
    }
  });

  // The sampler: RSS every second, a progress line every report_every seconds.
  std::vector<Sample> samples;
  const double cpu0 = cpu_seconds(pid), own0 = own_cpu_seconds();
  std::printf("%7s %9s %10s %14s %15s %18s %9s\n", "t [s]", "RSS MiB", "updates/s",
              "ed. frames/s", "watch frames/s", "lat p50/p99 ms", "srv CPU");
  Sample last_report{0, rss_mib(pid), 0, 0, 0};
  double last_cpu = cpu0;
  for (int k = 1;; ++k) {
    const auto at = t0 + std::chrono::seconds(k);
    if (at > end) break;
    std::this_thread::sleep_until(at);
    Sample s{seconds_between(t0, Clock::now()), rss_mib(pid), shared.updates_sent.load(),
             shared.editor_frames.load(), shared.watcher_frames.load()};
    samples.push_back(s);
    if (k % report_every == 0) {
      std::vector<float> recent;
      for (auto& e : edit) e->take_recent(recent);
      std::sort(recent.begin(), recent.end());
      const double dt = s.t - last_report.t;
      const double cpu = cpu_seconds(pid);
      std::printf("%7.0f %9.1f %10.0f %14.0f %15.0f %8.1f / %7.1f %8.0f%%\n", s.t, s.rss,
                  static_cast<double>(s.updates - last_report.updates) / dt,
                  static_cast<double>(s.editor_frames - last_report.editor_frames) / dt,
                  static_cast<double>(s.watcher_frames - last_report.watcher_frames) / dt,
                  percentile_sorted(recent, 0.5), percentile_sorted(recent, 0.99),
                  cpu >= 0 ? 100.0 * (cpu - last_cpu) / dt : -1.0);
      std::fflush(stdout);
      last_report = s;
      last_cpu = cpu;
    }
  }
  stop_driver = true;
  driver.join();
  const double stream_s = seconds_between(t0, Clock::now());
  const double server_cpu = cpu_seconds(pid) - cpu0, own_cpu = own_cpu_seconds() - own0;

  // --- the end: editors half-close, then the sessions are deleted ---------------------------
  const auto drain0 = Clock::now();
  for (auto& e : edit) e->close();
  if (!shared.wait_for(shared.editors_done, static_cast<int>(edit.size()),
                       std::chrono::seconds(30))) {
    shared.error("Deform streams still open 30 s after the half-close (cancelled)");
    for (auto& e : edit) {
      e->mark_cancelled();
      e->cancel();
    }
    shared.wait_for(shared.editors_done, static_cast<int>(edit.size()), std::chrono::seconds(30));
  }
  const double drain_s = seconds_between(drain0, Clock::now());
  shared.stopping = true;
  for (std::size_t i = 0; i < plans.size(); ++i) {
    pb::DeleteSessionRequest req;
    req.set_name(plans[i].name);
    pb::DeleteSessionResponse resp;
    auto st = with_deadline(
        [&](grpc::ClientContext& ctx) {
          return stubs[i % stubs.size()]->DeleteSession(&ctx, req, &resp);
        },
        plans[i].edit_token);
    if (!st.ok()) shared.error("DeleteSession " + plans[i].name + ": " + status_text(st));
  }
  // Deleting a session ends its watchers with `deleted` + OK; whoever is still open after
  // 15 s is cancelled by us (reported, not an error).
  if (!shared.wait_for(shared.watchers_done, static_cast<int>(watch.size()),
                       std::chrono::seconds(15))) {
    for (auto& w : watch) w->cancel();
    shared.wait_for(shared.watchers_done, static_cast<int>(watch.size()), std::chrono::seconds(15));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));  // let the server free what it frees
  const double rss_deleted = rss_mib(pid);

  // --- report -----------------------------------------------------------------------------
  std::vector<float> frame_lat, update_lat;
  int newest_answered = 0;
  std::int64_t unanswered = 0;
  for (const auto& e : edit) {
    frame_lat.insert(frame_lat.end(), e->frame_latencies().begin(), e->frame_latencies().end());
    update_lat.insert(update_lat.end(), e->update_latencies().begin(),
                      e->update_latencies().end());
    newest_answered += e->newest_answered() ? 1 : 0;
    unanswered += e->unanswered();
  }
  std::sort(frame_lat.begin(), frame_lat.end());
  std::sort(update_lat.begin(), update_lat.end());
  std::vector<double> watcher_fps;
  int saw_deleted = 0, cancelled_at_end = 0;
  for (const auto& w : watch) {
    watcher_fps.push_back(static_cast<double>(w->frames()) / stream_s);
    saw_deleted += w->saw_deleted() ? 1 : 0;
    cancelled_at_end += w->cancelled_at_end() ? 1 : 0;
  }
  std::sort(watcher_fps.begin(), watcher_fps.end());

  const auto updates = shared.updates_sent.load();
  const auto eframes = shared.editor_frames.load();
  const auto wframes = shared.watcher_frames.load();
  std::printf("\n== summary ==\n");
  std::printf("streaming %.1f s (then %.1f s for the editors to drain); set-up %.1f s\n", stream_s,
              drain_s, setup_s);
  std::printf("clients: %d sessions × (%d editors at %.0f Hz + %d watchers) = %zu streams on %d "
              "connections\n",
              sessions, editors, rate, watchers, edit.size() + watch.size(), nchannels);
  std::printf("updates sent: %lld (%.0f/s; target %.0f/s), driver ticks skipped: %lld, "
              "coalesced in the client: %lld\n",
              static_cast<long long>(updates), static_cast<double>(updates) / stream_s,
              rate * static_cast<double>(edit.size()), static_cast<long long>(skipped_ticks.load()),
              static_cast<long long>(shared.client_coalesced.load()));
  std::printf("editor frames: %lld (%.0f/s, %.1f %% of the updates; the rest coalesced by the "
              "server, latest wins)\n",
              static_cast<long long>(eframes), static_cast<double>(eframes) / stream_s,
              updates > 0 ? 100.0 * static_cast<double>(eframes) / static_cast<double>(updates) : 0);
  const double per_watcher_expected =
      static_cast<double>(eframes) / static_cast<double>(std::max(1, sessions));
  std::printf("watcher frames: %lld (%.0f/s); per watcher %.1f / %.1f / %.1f frames/s "
              "(min / median / max); %.1f %% of their sessions' frames\n",
              static_cast<long long>(wframes), static_cast<double>(wframes) / stream_s,
              watcher_fps.empty() ? 0 : watcher_fps.front(),
              watcher_fps.empty() ? 0 : watcher_fps[watcher_fps.size() / 2],
              watcher_fps.empty() ? 0 : watcher_fps.back(),
              watch.empty() || eframes == 0
                  ? 0
                  : 100.0 * static_cast<double>(wframes) /
                        (per_watcher_expected * static_cast<double>(watch.size())));
  std::printf("watcher state events: %lld; presence/step/timeline events: %lld; watchers that "
              "got `deleted` at the end: %d / %zu; cancelled by the bench at the end: %d\n",
              static_cast<long long>(shared.watcher_states.load()),
              static_cast<long long>(shared.watcher_other.load()), saw_deleted, watch.size(),
              cancelled_at_end);
  std::printf("latency per frame  (frame − send of its own sequence): p50 %.1f  p90 %.1f  p99 "
              "%.1f  max %.1f ms  (n = %zu)\n",
              percentile_sorted(frame_lat, 0.5), percentile_sorted(frame_lat, 0.9),
              percentile_sorted(frame_lat, 0.99), percentile_sorted(frame_lat, 1.0),
              frame_lat.size());
  std::printf("latency per update (send s → first frame ≥ s):        p50 %.1f  p90 %.1f  p99 "
              "%.1f  max %.1f ms  (n = %zu)\n",
              percentile_sorted(update_lat, 0.5), percentile_sorted(update_lat, 0.9),
              percentile_sorted(update_lat, 0.99), percentile_sorted(update_lat, 1.0),
              update_lat.size());
  std::printf("newest update answered at the half-close: %d / %zu editors (unanswered updates: "
              "%lld)\n",
              newest_answered, edit.size(), static_cast<long long>(unanswered));
  if (pid > 0) {
    std::vector<std::pair<double, double>> second_half;
    double lo = 1e300, hi = -1e300;
    for (const auto& s : samples)
      if (s.t >= stream_s / 2 && s.rss >= 0) {
        second_half.emplace_back(s.t / 60.0, s.rss);
        lo = std::min(lo, s.rss);
        hi = std::max(hi, s.rss);
      }
    std::printf("server RSS: %.1f MiB idle, %.1f after set-up, %.1f at the end of streaming, "
                "%.1f after deleting the sessions\n",
                rss_idle, rss_setup, samples.empty() ? -1.0 : samples.back().rss, rss_deleted);
    if (!second_half.empty())
      std::printf("server RSS, second half (t ≥ %.0f s): min %.1f, max %.1f MiB, slope %+.2f "
                  "MiB/min (%zu samples)\n",
                  stream_s / 2, lo, hi, slope(second_half), second_half.size());
    std::printf("server CPU: %.0f %% of one core on average; this bench: %.0f %%\n",
                100.0 * server_cpu / stream_s, 100.0 * own_cpu / stream_s);
  } else {
    std::printf("server RSS: not sampled (give --server-pid with --server)\n");
  }
  if (!curve_csv.empty()) {
    std::ofstream csv(curve_csv);
    csv << "t_s,rss_mib,updates,editor_frames,watcher_frames\n";
    for (const auto& s : samples)
      csv << s.t << "," << s.rss << "," << s.updates << "," << s.editor_frames << ","
          << s.watcher_frames << "\n";
  }
  std::printf("errors: %lld\n", static_cast<long long>(shared.error_count.load()));
  {
    std::lock_guard lock(shared.error_mu);
    int shown = 0;
    for (const auto& [what, n] : shared.errors) {
      if (++shown > 20) {
        std::printf("  … %zu kinds in all\n", shared.errors.size());
        break;
      }
      std::printf("  %lld× %s\n", static_cast<long long>(n), what.c_str());
    }
  }
  if (child) {
    std::printf("server: %s; %ld log lines at warn or above during the run\n",
                child->stop().c_str(), child->log_lines());
  }
  std::printf("load average at the end: %s\n", loadavg().c_str());
  // The reactors must outlive their calls (all done above); the stubs and channels go last.
  edit.clear();
  watch.clear();
  return shared.error_count.load() == 0 ? 0 : 1;
}
