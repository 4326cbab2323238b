// hdeform watch SESSION: one line per frame and state change of a live session.
#include "commands.h"
#include "frame_decode.h"
#include "output.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <algorithm>
#include <cctype>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

namespace hdeform::cli {

namespace {

struct WatchOptions {
  std::string session;
  long count = 0;         // stop after this many events (0 = until the session ends)
  double duration = 0;    // stop after this many seconds (0 = no limit)
  pb::FrameEncoding encoding = pb::FRAME_ENCODING_FLOAT32;
  bool exact_float32 = false;
};

std::string frame_encoding_name(pb::FrameEncoding e) {
  switch (e) {
    case pb::FRAME_ENCODING_FLOAT32: return "float32";
    case pb::FRAME_ENCODING_QUANTIZED: return "quantized";
    case pb::FRAME_ENCODING_MESHOPT: return "meshopt";
    case pb::FRAME_ENCODING_MESHOPT_DELTA: return "meshopt-delta";
    case pb::FRAME_ENCODING_FLOAT64: return "float64";
    default: return std::to_string(static_cast<int>(e));
  }
}

std::string frame_line(const pb::Frame& f) {
  std::ostringstream s;
  s << "frame seq=" << f.sequence() << " version=" << f.version() << " beta=" << shortest(f.beta().value())
    << (f.beta().units() == pb::BETA_UNITS_RAW ? "(raw)" : "");
  for (const auto& c : measure_columns()) {
    const double v = c.get(f.measures());
    s << " " << c.csv << "=" << (c.integer ? std::to_string(static_cast<long long>(v)) : g6(v));
  }
  s << " solve_ms=" << g6(f.solve_ms()) << " exact=" << (f.exact() ? 1 : 0)
    << " encoding=" << frame_encoding_name(f.encoding()) << " bytes=" << frame_buffer_bytes(f);
  if (f.encoding() == pb::FRAME_ENCODING_MESHOPT_DELTA) s << " delta=" << (f.delta() ? 1 : 0);
  return s.str();
}

std::string state_line(const pb::Session& st) {
  std::ostringstream s;
  s << "state " << st.name() << " version=" << st.version() << " mesh=" << st.mesh_name()
    << " vertices=" << st.vertex_count() << " triangles=" << st.triangle_count()
    << " fixed=" << st.constraints().fixed().ids_size()
    << " handles=" << st.constraints().handles_size() << " beta=" << shortest(st.beta().value())
    << (st.beta().units() == pb::BETA_UNITS_RAW ? "(raw)" : "") << " observers=" << st.observers();
  return s.str();
}

// Who is here: one entry per participant, "name(client_id)" with its role and held handles.
std::string presence_line(const pb::Presence& p) {
  std::ostringstream s;
  s << "presence version=" << p.version() << " participants=" << p.participants_size();
  for (const auto& who : p.participants()) {
    s << " " << (who.display_name().empty() ? "anonymous" : who.display_name()) << "("
      << who.client_id() << (who.editor() ? ",editor" : ",viewer")
      << (who.watching() ? ",watching" : "");
    if (who.held_handles_size() > 0) {
      s << ",holds=";
      for (int i = 0; i < who.held_handles_size(); ++i)
        s << (i ? "+" : "") << who.held_handles(i);
    }
    s << ")";
  }
  return s.str();
}

std::string step_line(const pb::HistoryStep& st) {
  std::string kind = pb::StepKind_Name(st.kind());
  kind = kind.substr(kind.rfind("STEP_KIND_") == 0 ? 10 : 0);
  std::transform(kind.begin(), kind.end(), kind.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  std::ostringstream s;
  s << "step id=" << st.id() << " kind=" << kind << " version=" << st.version()
    << " author=" << (st.author().empty() ? "anonymous" : st.author()) << " summary=\""
    << st.summary() << "\"";
  return s.str();
}

std::string timeline_line(const pb::Timeline& t) {
  std::ostringstream s;
  s << "timeline version=" << t.version() << " keys=" << t.keys_size() << " easing="
    << (t.easing() == pb::EASING_SMOOTHSTEP ? "smoothstep" : "linear");
  if (t.keys_size() > 0) s << " end_s=" << shortest(t.keys(t.keys_size() - 1).time_s());
  return s.str();
}

}  // namespace

Command add_watch_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<WatchOptions>();
  auto* cmd = app.add_subcommand(
      "watch", "print the frames and state changes of a live session (needs --server)");
  cmd->add_option("SESSION", opts->session, "sessions/ID or ID")->required();
  cmd->add_option("--count", opts->count,
                  "stop after N printed events (lines) (default: until the session ends)");
  cmd->add_option("--for", opts->duration, "stop after S seconds");
  cmd->add_option("--encoding", opts->encoding,
                  "frame buffers: float32 (exact), quantized (16-bit positions, 8-bit "
                  "octahedral normals), meshopt (quantized, compressed) or meshopt-delta "
                  "(meshopt of the differences to the previous frame); every frame is "
                  "decoded and checked")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, pb::FrameEncoding>{{"float32", pb::FRAME_ENCODING_FLOAT32},
                                                   {"quantized", pb::FRAME_ENCODING_QUANTIZED},
                                                   {"meshopt", pb::FRAME_ENCODING_MESHOPT},
                                                   {"meshopt-delta", pb::FRAME_ENCODING_MESHOPT_DELTA}},
          CLI::ignore_case));
  cmd->add_flag("--exact-float32", opts->exact_float32,
                "exact frames (the one ending a drag) as float32 whatever --encoding says");

  return [opts, &global]() -> int {
    const auto& o = *opts;
    if (global.server.empty())
      throw CliError("watch needs --server HOST:PORT (an in-process service has no sessions)");
    Connection conn(global);
    const std::string name = session_name_of(o.session);
    const std::string id = session_id_of(name);
    pb::WatchSessionRequest req;
    req.set_name(name);
    req.mutable_format()->set_encoding(o.encoding);
    req.mutable_format()->set_exact_as_float32(o.exact_float32);

    // --for: cancel the current stream from a timer thread.
    std::atomic<bool> timed_out{false};
    std::mutex mu;
    std::condition_variable cv;
    bool done = false;
    grpc::ClientContext* current = nullptr;  // guarded by mu
    std::thread timer;
    if (o.duration > 0) {
      timer = std::thread([&] {
        std::unique_lock lock(mu);
        if (!cv.wait_for(lock, std::chrono::duration<double>(o.duration), [&] { return done; })) {
          timed_out = true;
          if (current) current->TryCancel();
        }
      });
    }
    auto stop_timer = [&] {
      {
        std::lock_guard lock(mu);
        done = true;
      }
      cv.notify_all();
      if (timer.joinable()) timer.join();
    };

    long events = 0;
    std::size_t vertices = 0, triangles = 0;  // from the state event, which comes first
    std::string bad_frame;                    // a frame that did not decode
    bool deleted = false;
    bool may_reopen = true;
    grpc::Status status;
    for (;;) {
      grpc::ClientContext ctx;
      conn.prepare(ctx, id, 0, TokenScope::kSession, id);  // a stream: no deadline
      {
        std::lock_guard lock(mu);
        current = &ctx;
        if (timed_out) ctx.TryCancel();
      }
      auto reader = conn.stub().WatchSession(&ctx, req);
      FrameStreamDecoder decoder;  // per stream: MESHOPT_DELTA's state starts at its key frame
      const long before = events;
      pb::SessionEvent ev;
      while (reader->Read(&ev)) {
        switch (ev.event_case()) {
          case pb::SessionEvent::kFrame:
            try {
              decoder.decode(ev.frame(), vertices, triangles);
            } catch (const FrameDecodeError& e) {
              bad_frame = e.what();
            }
            if (bad_frame.empty()) std::cout << frame_line(ev.frame()) << std::endl;
            break;
          case pb::SessionEvent::kState:
            vertices = static_cast<std::size_t>(std::max(0, ev.state().vertex_count()));
            triangles = static_cast<std::size_t>(std::max(0, ev.state().triangle_count()));
            std::cout << state_line(ev.state()) << std::endl;
            break;
          case pb::SessionEvent::kDeleted:
            std::cout << "deleted " << ev.deleted() << std::endl;
            deleted = true;
            break;
          case pb::SessionEvent::kPresence:
            std::cout << presence_line(ev.presence()) << std::endl;
            break;
          case pb::SessionEvent::kStep:
            std::cout << step_line(ev.step()) << std::endl;
            break;
          case pb::SessionEvent::kTimeline:
            std::cout << timeline_line(ev.timeline()) << std::endl;
            break;
          default: continue;  // an event this client does not know: neither printed nor counted
        }
        ++events;
        if (!bad_frame.empty() || deleted || (o.count > 0 && events >= o.count)) {
          ctx.TryCancel();
          break;
        }
      }
      status = reader->Finish();
      {
        std::lock_guard lock(mu);
        current = nullptr;
      }
      if (!bad_frame.empty()) {
        stop_timer();
        throw CliError("WatchSession: " + bad_frame);
      }
      const bool stopped = timed_out || deleted || (o.count > 0 && events >= o.count);
      // The retry policy for streams: a stream cut by UNAVAILABLE (the server restarted, a
      // replica died) is reopened once; a reopened stream that delivered events may be
      // reopened again after a later cut.
      if (events > before) may_reopen = true;
      if (status.error_code() == grpc::StatusCode::UNAVAILABLE && !stopped && may_reopen) {
        may_reopen = false;
        conn.wait_before_retry("WatchSession");
        continue;
      }
      break;
    }
    stop_timer();
    if (!status.ok() && !(status.error_code() == grpc::StatusCode::CANCELLED &&
                          (timed_out || deleted || (o.count > 0 && events >= o.count))))
      throw RpcError("WatchSession", status);
    return 0;
  };
}

}  // namespace hdeform::cli
