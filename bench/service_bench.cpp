// hdeform service benchmarks over loopback TCP (Google Benchmark). How to run and the
// measured numbers: docs/benchmarks.md, "Service (loopback)".
//
// An in-process hdeform::service::Server listens on 127.0.0.1:0; the benchmark talks to it
// through a real TCP channel (grpc::CreateCustomChannel), so every frame is serialized,
// sent over loopback and parsed like for a remote client. The mesh is the procedural
// capsule (bench/procedural.h) uploaded as binary little-endian PLY (exact doubles, file
// vertex order = engine order) through the client-streaming CreateSession; constraints are
// the base (fixed) and the cap (one handle), by vertex ids; β = 0 (area units).
//
// Families (N = nominal vertex count: 10000 or 100000):
//   Unary/N                one UpdateHandles per iteration (a new rotation every time);
//                          p50_ms / p99_ms of the round trip, server_p50_ms = Frame.solve_ms.
//   UnaryInProcess/N       the same over the server's in-process channel (no TCP).
//   Stream/N               Deform bidi stream with one update in flight: write, read frame.
//   Burst/N/updates:U      Deform stream: U updates written as fast as possible, frames
//                          read on a second thread; frames, frames/s, coalesced updates.
//   Drag/N/hz:H/updates:U  the same at a fixed rate (a user dragging at H Hz, every update
//                          but the last marked `dragging`, as the viewer sends them): fps,
//                          and p50/p99 latency from each answered update to its frame.
//   Drag/N/hz:20/updates:U/ENC
//                          at 20 Hz (no queue behind a move) with frames in encoding ENC:
//                          over_p50_ms (median of latency − Frame.solve_ms) is what the
//                          stream, the encode and the client add to the move.
//   Unary/N/ENC            Unary with frames in encoding ENC (quantized, meshopt).
//   Encode/N/ENC           the server's encoder alone on one real frame of the capsule (its
//                          first move, with normals and energies): time per encoding; bytes
//                          (positions + normals + energies) per frame and the client decoder's
//                          time (client-cli/frame_decode.h) as counters.
//   Restore/N              a stored session restored by a restarted server (SQLite store in a
//                          temp folder): the first GetSession's time (parse, prepare, resolve,
//                          factorize) with the solver's orderings kept in the store and with
//                          them deleted, alternated each iteration: kept_p50_ms, cold_p50_ms,
//                          cold_over_kept. Time column meaningless.
//   Memory/N/{distinct,shared}/sessions:K
//                          VmRSS delta for K sessions (CreateSession + SetConstraints + one
//                          UpdateHandles each) on K distinct meshes or on one mesh; a fresh
//                          server per run. first_* = the first session, extra_* = each
//                          later one. Time column meaningless.
// Percentiles are nearest-rank over the iterations of one run (Google Benchmark's own
// time column is the mean).
//
// Extra flags (ours): --hdeform_smoke  a handful of iterations everywhere (ctest bench-smoke);
//   --hdeform_warm_cores_ms=MS  as hdeform-server's --warm-cores-ms (0: cores may halt
//                           between drag moves)
//   --hdeform_state_dir=DIR  the latency server keeps its sessions in a SQLite store in DIR
//   (as hdeform-server --state-dir), so moves and changes pass the store step.
#include "bench_common.h"
#include "capsule_upload.h"
#include "engine/runtime/process_environment.h"
#include "engine/runtime/warm_cores.h"
#include "fixtures/procedural.h"
#include "frame_decode.h"
#include "hdeform/v1/deform.grpc.pb.h"
#include "service/frames/frame_delta.h"
#include "service/frames/frame_encoding.h"
#include "service/rpc/server.h"

#include <benchmark/benchmark.h>
#include <grpcpp/grpcpp.h>
#include <malloc.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace {

using namespace hdeform;
namespace pb = ::hdeform::v1;
using Clock = std::chrono::steady_clock;

bool g_smoke = false;

double ms_since(Clock::time_point t0, Clock::time_point t1 = Clock::now()) {
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

// Nearest-rank percentile (q in (0, 1]).
double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

double rss_bytes() {
  malloc_trim(0);  // return freed heap pages so the delta counts live memory
  const double kb = bench::status_kb("VmRSS");
  return kb < 0 ? -1 : kb * 1024.0;
}

// Binary little-endian PLY: double x y z, uchar/int faces (the service's own reader).
std::string ply_bytes(const TriMesh& mesh) {
  std::ostringstream h;
  h << "ply\nformat binary_little_endian 1.0\nelement vertex " << mesh.num_vertices()
    << "\nproperty double x\nproperty double y\nproperty double z\nelement face "
    << mesh.num_triangles() << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::string out = h.str();
  const std::size_t header = out.size();
  out.resize(header + 24u * mesh.num_vertices() + 13u * mesh.num_triangles());
  char* p = out.data() + header;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    for (int c = 0; c < 3; ++c) {
      const double x = mesh.V(v, c);
      std::memcpy(p, &x, 8);
      p += 8;
    }
  for (int f = 0; f < mesh.num_triangles(); ++f) {
    *p++ = 3;
    for (int c = 0; c < 3; ++c) {
      const std::int32_t i = mesh.F(f, c);
      std::memcpy(p, &i, 4);
      p += 4;
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// Every call presents the bench server's operator token (the bench measures the deformation
// path, not access control: one constant-time hash compare per call).
const std::string kBenchToken = "service-bench-operator-token-0123456789";
void authorize(grpc::ClientContext& ctx) {
  ctx.AddMetadata("authorization", "Bearer " + kBenchToken);
}

// --hdeform_state_dir=DIR: the bench server keeps its sessions in a SQLite store there, so
// every move and change also passes the store step (docs/architecture.md "One path for a
// change"); empty: in memory only, as hdeform-server without --state-dir.
std::string g_state_dir;

// A server on 127.0.0.1:0 and a TCP channel to it.
struct Loopback {
  std::unique_ptr<service::Server> server;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<pb::Deformation::Stub> stub;

  explicit Loopback(
      const std::string& state_dir = g_state_dir,
      std::size_t background_order_from = service::ServerOptions{}.background_order_from) {
    service::ServerOptions o;  // defaults of hdeform-server: 2 workers, 4 GiB cache
    o.listen_address = "127.0.0.1:0";
    o.background_order_from = background_order_from;
    o.admin_token = kBenchToken;
    o.state_dir = state_dir;
    server = std::make_unique<service::Server>(o);
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    args.SetMaxSendMessageSize(-1);
    channel = grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(server->port()),
                                        grpc::InsecureChannelCredentials(), args);
    if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10)))
      throw std::runtime_error("cannot connect to the loopback server");
    stub = pb::Deformation::NewStub(channel);
  }
  ~Loopback() {
    stub.reset();
    channel.reset();
    server->shutdown(std::chrono::milliseconds(1000));
  }
};

std::unique_ptr<Loopback> g_main;  // the latency server (created in main)
std::unique_ptr<pb::Deformation::Stub> g_in_process_stub;  // UnaryInProcess

grpc::Status upload(pb::Deformation::Stub& stub, const std::string& filename,
                    const std::string& bytes, pb::Session* out) {
  grpc::ClientContext ctx;
  authorize(ctx);
  return bench::upload_mesh(stub, ctx, filename, bytes, out);
}

grpc::Status constrain(pb::Deformation::Stub& stub, const std::string& name,
                       const procedural::CapsuleCase& c) {
  grpc::ClientContext ctx;
  authorize(ctx);
  pb::SetConstraintsRequest req;
  req.set_name(name);
  *req.mutable_constraints() = bench::capsule_constraints(c);
  pb::Session out;
  return stub.SetConstraints(&ctx, req, &out);
}

// Handle move number k: the cap tilted about x by ≈ 29° (a different angle every k) and
// pulled sideways by 1.5, as in engine_bench.
void set_move(pb::HandleTransform* t, std::int64_t k) {
  const double angle = 0.5 + 1e-4 * static_cast<double>(k % 2000);
  auto* q = t->mutable_rotation();
  q->set_w(std::cos(angle / 2));
  q->set_x(std::sin(angle / 2));
  q->set_y(0);
  q->set_z(0);
  t->mutable_translation()->set_x(1.5);
}

grpc::Status update_once(pb::Deformation::Stub& stub, const std::string& name, std::int64_t k,
                         pb::Frame* frame,
                         pb::FrameEncoding encoding = pb::FRAME_ENCODING_FLOAT32,
                         bool energies = false) {
  grpc::ClientContext ctx;
  authorize(ctx);
  pb::UpdateHandlesRequest req;
  req.set_name(name);
  req.set_sequence(k);
  set_move(req.add_transforms(), k);
  req.mutable_format()->set_encoding(encoding);
  req.set_energies(energies);
  return stub.UpdateHandles(&ctx, req, frame);
}

const char* encoding_name(pb::FrameEncoding e) {
  return e == pb::FRAME_ENCODING_MESHOPT ? "meshopt"
         : e == pb::FRAME_ENCODING_QUANTIZED ? "quantized" : "float32";
}

// One session per size on the latency server, built on first use.
struct Case {
  procedural::CapsuleCase capsule;
  std::string name;
  int vertices = 0;
  std::size_t upload_bytes = 0;
  double create_ms = 0, constrain_ms = 0;
};
std::map<int, std::unique_ptr<Case>> g_cases;
std::int64_t g_move = 1;  // a new move for every request of the run

Case* get_case(int n, benchmark::State& state) {
  auto& slot = g_cases[n];
  if (slot) return slot.get();
  auto c = std::make_unique<Case>();
  c->capsule = procedural::capsule_case(n);
  const std::string bytes = ply_bytes(c->capsule.mesh);
  c->upload_bytes = bytes.size();
  pb::Session s;
  auto t0 = Clock::now();
  auto status = upload(*g_main->stub, "capsule" + std::to_string(n) + ".ply", bytes, &s);
  c->create_ms = ms_since(t0);
  if (!status.ok()) {
    state.SkipWithError(("CreateSession: " + status.error_message()).c_str());
    return nullptr;
  }
  c->name = s.name();
  c->vertices = s.vertex_count();
  t0 = Clock::now();
  status = constrain(*g_main->stub, c->name, c->capsule);
  c->constrain_ms = ms_since(t0);
  if (!status.ok()) {
    state.SkipWithError(("SetConstraints: " + status.error_message()).c_str());
    return nullptr;
  }
  for (int i = 0; i < 3; ++i) {  // warm-up: first frames allocate
    pb::Frame f;
    update_once(*g_main->stub, c->name, g_move++, &f);
  }
  slot = std::move(c);
  return slot.get();
}

void common_counters(benchmark::State& state, const Case& c) {
  state.counters["vertices"] = c.vertices;
  state.counters["open_ms"] = c.create_ms + c.constrain_ms;  // CreateSession + SetConstraints
}

// ---------------------------------------------------------------------------------------
// in_process: the same calls over the server's in-process channel (no TCP, no HTTP/2
// framing; messages are still serialized), to separate the network share of the overhead.
void BM_Unary(benchmark::State& state, int n, bool in_process, pb::FrameEncoding encoding) {
  Case* c = get_case(n, state);
  if (!c) return;
  if (in_process && !g_in_process_stub)
    g_in_process_stub = pb::Deformation::NewStub(g_main->server->in_process_channel());
  pb::Deformation::Stub& stub = in_process ? *g_in_process_stub : *g_main->stub;
  std::vector<double> total, server;
  std::size_t frame_bytes = 0;
  for (auto _ : state) {
    pb::Frame frame;
    const auto t0 = Clock::now();
    const auto status = update_once(stub, c->name, g_move++, &frame, encoding);
    total.push_back(ms_since(t0));
    if (!status.ok()) {
      state.SkipWithError(("UpdateHandles: " + status.error_message()).c_str());
      break;
    }
    server.push_back(frame.solve_ms());
    frame_bytes = frame.ByteSizeLong();
  }
  common_counters(state, *c);
  state.counters["p50_ms"] = percentile(total, 0.5);
  state.counters["p99_ms"] = percentile(total, 0.99);
  state.counters["max_ms"] = percentile(total, 1.0);
  state.counters["server_p50_ms"] = percentile(server, 0.5);  // Frame.solve_ms
  state.counters["frame_MB"] = static_cast<double>(frame_bytes) / 1e6;
}

void BM_Encode(benchmark::State& state, int n, pb::FrameEncoding encoding) {
  Case* c = get_case(n, state);
  if (!c) return;
  auto frame = std::make_shared<pb::Frame>();
  const auto status = update_once(*g_main->stub, c->name, g_move++, frame.get(),
                                  pb::FRAME_ENCODING_FLOAT32, true);
  if (!status.ok()) {
    state.SkipWithError(("UpdateHandles: " + status.error_message()).c_str());
    return;
  }
  pb::FrameFormat format;
  format.set_encoding(encoding);
  std::shared_ptr<const pb::Frame> out;
  for (auto _ : state) {
    out = service::encode_frame(frame, format);
    benchmark::DoNotOptimize(out.get());
  }
  std::vector<double> decode;
  const auto triangles = static_cast<std::size_t>(c->capsule.mesh.num_triangles());
  for (int i = 0; i < 5; ++i) {
    const auto t0 = Clock::now();
    const auto d = cli::decode_frame(*out, static_cast<std::size_t>(c->vertices), triangles);
    decode.push_back(ms_since(t0));
    benchmark::DoNotOptimize(d.positions.data());
  }
  common_counters(state, *c);
  state.counters["frame_MB"] = static_cast<double>(cli::frame_buffer_bytes(*out)) / 1e6;
  state.counters["bytes_per_vertex"] =
      static_cast<double>(out->positions().size() + out->normals().size() + out->vertices().size()) /
      c->vertices;
  state.counters["decode_ms"] = percentile(decode, 0.5);
}

// MESHOPT_DELTA: one watcher's encoder fed two frames of a drag in turn (moves `apart`
// apart, as set_move numbers them: 300 ≈ 1.7° of the cap's tilt), so every encode is a delta
// of that size; the C++ stream decoder times the decode of the last one.
void BM_EncodeDelta(benchmark::State& state, int n, int apart) {
  Case* c = get_case(n, state);
  if (!c) return;
  pb::Frame frames[2];
  for (int i = 0; i < 2; ++i) {
    const auto status = update_once(*g_main->stub, c->name, g_move + i * apart, &frames[i]);
    if (!status.ok()) {
      state.SkipWithError(("UpdateHandles: " + status.error_message()).c_str());
      return;
    }
  }
  g_move += 2 * apart;
  service::FrameDeltaEncoder encoder;
  pb::Frame out, key;
  encoder.encode(frames[0], &key);
  int i = 1;
  for (auto _ : state) {
    encoder.encode(frames[i], &out);
    benchmark::DoNotOptimize(out.vertices().data());
    i ^= 1;
  }
  if (!out.delta()) {
    state.SkipWithError("the frames left the key frame's grid: not a delta");
    return;
  }
  const auto vertices = static_cast<std::size_t>(c->vertices);
  std::vector<double> decode;
  for (int k = 0; k < 5; ++k) {
    cli::FrameStreamDecoder decoder;
    decoder.decode(key, vertices, 0);
    pb::Frame delta;
    encoder.reset();
    encoder.encode(frames[0], &delta);  // a key frame again, then the delta to frames[1]
    encoder.encode(frames[1], &delta);
    const auto t0 = Clock::now();
    const auto d = decoder.decode(delta, vertices, 0);
    decode.push_back(ms_since(t0));
    benchmark::DoNotOptimize(d.positions.data());
  }
  common_counters(state, *c);
  state.counters["key_MB"] = static_cast<double>(key.vertices().size()) / 1e6;
  state.counters["delta_MB"] = static_cast<double>(out.vertices().size()) / 1e6;
  state.counters["bytes_per_vertex"] = static_cast<double>(out.vertices().size()) / c->vertices;
  state.counters["decode_ms"] = percentile(decode, 0.5);
}

void BM_Stream(benchmark::State& state, int n) {
  Case* c = get_case(n, state);
  if (!c) return;
  grpc::ClientContext ctx;
  authorize(ctx);
  auto stream = g_main->stub->Deform(&ctx);
  std::vector<double> total, server;
  bool first = true;
  for (auto _ : state) {
    pb::DeformRequest req;
    if (first) req.set_name(c->name);
    first = false;
    const std::int64_t k = g_move++;
    req.set_sequence(k);
    set_move(req.add_transforms(), k);
    pb::Frame frame;
    const auto t0 = Clock::now();
    if (!stream->Write(req) || !stream->Read(&frame)) {
      state.SkipWithError("Deform stream broke");
      break;
    }
    total.push_back(ms_since(t0));
    server.push_back(frame.solve_ms());
    if (frame.sequence() != k) {
      state.SkipWithError("Deform answered another sequence");
      break;
    }
  }
  stream->WritesDone();
  pb::Frame rest;
  while (stream->Read(&rest)) {
  }
  const auto status = stream->Finish();
  if (!status.ok()) state.SkipWithError(("Deform: " + status.error_message()).c_str());
  common_counters(state, *c);
  state.counters["p50_ms"] = percentile(total, 0.5);
  state.counters["p99_ms"] = percentile(total, 0.99);
  state.counters["max_ms"] = percentile(total, 1.0);
  state.counters["server_p50_ms"] = percentile(server, 0.5);
}

// `updates` updates on one Deform stream, `interval_us` apart (0 = as fast as possible),
// frames read on a second thread.
void BM_Burst(benchmark::State& state, int n, int updates, int interval_us,
              pb::FrameEncoding encoding) {
  Case* c = get_case(n, state);
  if (!c) return;
  std::vector<double> frames_v, fps_v, coalesced_v, last_ms_v, send_ms_v, lat, server, over;
  std::vector<double> plain;  // Frame.solve_ms of drag frames without measures
  bool newest_answered = true;
  for (auto _ : state) {
    grpc::ClientContext ctx;
    authorize(ctx);
    auto stream = g_main->stub->Deform(&ctx);
    const std::int64_t base = g_move;
    g_move += updates;
    std::vector<std::atomic<std::int64_t>> sent_ns(static_cast<std::size_t>(updates));
    const auto t0 = Clock::now();
    int frames = 0;
    std::int64_t last_seq = 0;
    Clock::time_point last_frame = t0;
    std::thread reader([&] {
      pb::Frame frame;
      while (stream->Read(&frame)) {
        const auto now = Clock::now();
        ++frames;
        last_seq = frame.sequence();
        last_frame = now;
        server.push_back(frame.solve_ms());
        if (!frame.exact() && !frame.has_measures()) plain.push_back(frame.solve_ms());
        const std::int64_t i = frame.sequence() - base;
        if (i >= 0 && i < updates) {
          const auto sent = Clock::time_point(Clock::duration(sent_ns[i].load()));
          lat.push_back(ms_since(sent, now));
          over.push_back(lat.back() - frame.solve_ms());
        }
      }
    });
    for (int i = 0; i < updates; ++i) {
      if (interval_us > 0)
        std::this_thread::sleep_until(t0 + std::chrono::microseconds(
                                               static_cast<std::int64_t>(interval_us) * i));
      pb::DeformRequest req;
      if (i == 0) {
        req.set_name(c->name);
        req.mutable_format()->set_encoding(encoding);
      }
      req.set_sequence(base + i);
      req.set_dragging(interval_us > 0 && i + 1 < updates);  // a Burst is not a drag
      set_move(req.add_transforms(), base + i);
      sent_ns[i].store(Clock::now().time_since_epoch().count());
      if (!stream->Write(req)) break;
    }
    const double send_ms = ms_since(t0);
    stream->WritesDone();
    reader.join();
    const auto status = stream->Finish();
    if (!status.ok()) {
      state.SkipWithError(("Deform: " + status.error_message()).c_str());
      break;
    }
    const double last_ms = ms_since(t0, last_frame);
    frames_v.push_back(frames);
    last_ms_v.push_back(last_ms);
    send_ms_v.push_back(send_ms);
    fps_v.push_back(last_ms > 0 ? 1000.0 * frames / last_ms : 0);
    coalesced_v.push_back(updates - frames);
    newest_answered = newest_answered && last_seq == base + updates - 1;
  }
  common_counters(state, *c);
  state.counters["updates"] = updates;
  state.counters["frames"] = percentile(frames_v, 0.5);  // medians over the iterations
  state.counters["fps"] = percentile(fps_v, 0.5);
  state.counters["coalesced"] = percentile(coalesced_v, 0.5);
  state.counters["send_ms"] = percentile(send_ms_v, 0.5);
  state.counters["last_frame_ms"] = percentile(last_ms_v, 0.5);
  state.counters["newest_answered"] = newest_answered ? 1 : 0;  // last frame = last update
  state.counters["lat_p50_ms"] = percentile(lat, 0.5);  // answered update → its frame
  state.counters["lat_p99_ms"] = percentile(lat, 0.99);
  state.counters["server_p50_ms"] = percentile(server, 0.5);  // Frame.solve_ms
  state.counters["over_p50_ms"] = percentile(over, 0.5);  // latency − solve_ms, per frame
  // A drag frame has measures at most every 100 ms (at 20 Hz about three frames in five go
  // without): those are engine_bench's Update/N/beta:B/drag work (the drag solve, normals)
  // plus the service's encode, so the two compare like for like.
  state.counters["plain_frames"] = static_cast<double>(plain.size());
  state.counters["server_plain_p50_ms"] = percentile(plain, 0.5);
}

// K sessions on a fresh server; each: CreateSession (upload) + SetConstraints + one
// UpdateHandles (a session keeps its last frame).
void BM_Memory(benchmark::State& state, int n, bool distinct, int sessions) {
  static int variant = 0;  // every run uses meshes no server has seen
  const auto base_case = procedural::capsule_case(n);
  for (auto _ : state) {
    std::vector<std::string> files;
    for (int k = 0; k < (distinct ? sessions : 1); ++k) {
      TriMesh m = base_case.mesh;
      m.V.col(0).array() += 1e-3 * ++variant;  // another content hash, same ids
      files.push_back(ply_bytes(m));
    }
    Loopback lb;
    std::vector<std::string> names;
    auto open = [&](const std::string& bytes) {
      pb::Session s;
      auto status = upload(*lb.stub, "capsule.ply", bytes, &s);
      if (status.ok()) status = constrain(*lb.stub, s.name(), base_case);
      pb::Frame f;
      if (status.ok()) status = update_once(*lb.stub, s.name(), g_move++, &f);
      if (!status.ok()) state.SkipWithError(status.error_message().c_str());
      names.push_back(s.name());
      return status.ok();
    };
    // Warm the server and the channel (threads, arenas, first-call allocations) with a
    // tiny mesh of its own, so that they are in the baseline.
    {
      pb::Session s;
      upload(*lb.stub, "warm.ply", ply_bytes(procedural::capsule(8, 8)), &s);
    }
    const double base = rss_bytes();
    const auto t0 = Clock::now();
    if (!open(files[0])) break;
    const double first_ms = ms_since(t0);
    const double first = rss_bytes();
    const auto t1 = Clock::now();
    for (int k = 1; k < sessions; ++k)
      if (!open(files[distinct ? k : 0])) break;
    const double extra_ms = ms_since(t1);
    const double all = rss_bytes();
    state.counters["first_open_ms"] = first_ms;  // upload + parse + prepare + constrain + solve
    state.counters["extra_open_ms"] = sessions > 1 ? extra_ms / (sessions - 1) : 0;
    state.counters["sessions"] = sessions;
    state.counters["first_MB"] = (first - base) / 1e6;
    state.counters["total_MB"] = (all - base) / 1e6;
    state.counters["MB_per_session"] = (all - base) / sessions / 1e6;
    state.counters["extra_MB_per_session"] =  // each session after the first
        sessions > 1 ? (all - first) / (sessions - 1) / 1e6 : 0;
    state.counters["upload_MB"] = static_cast<double>(files[0].size()) / 1e6;
  }
}

// ---------------------------------------------------------------------------------------
void BM_Restore(benchmark::State& state, int n) {
  namespace fs = std::filesystem;
  std::string tmpl = (fs::temp_directory_path() / "hdeform-restore-XXXXXX").string();
  if (!::mkdtemp(tmpl.data())) {
    state.SkipWithError("mkdtemp failed");
    return;
  }
  const fs::path dir = tmpl;
  struct Remove {
    fs::path dir;
    ~Remove() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } remove{dir};
  const procedural::CapsuleCase capsule = procedural::capsule_case(n);
  std::string name;
  {
    Loopback lb(dir.string());
    pb::Session s;
    auto status = upload(*lb.stub, "capsule.ply", ply_bytes(capsule.mesh), &s);
    if (status.ok()) status = constrain(*lb.stub, s.name(), capsule);
    pb::Frame f;
    if (status.ok()) status = update_once(*lb.stub, s.name(), g_move++, &f);
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      return;
    }
    name = s.name();
  }  // a clean stop flushes the record and keeps the orderings
  std::vector<double> kept, cold;
  bool keep = true;
  for (auto _ : state) {
    if (!keep)
      for (const auto& e : fs::directory_iterator(dir / "derived")) fs::remove(e.path());
    Loopback lb(dir.string());
    grpc::ClientContext ctx;
    authorize(ctx);
    pb::GetSessionRequest req;
    req.set_name(name);
    pb::Session out;
    const auto t0 = Clock::now();
    const auto status = lb.stub->GetSession(&ctx, req, &out);
    (keep ? kept : cold).push_back(ms_since(t0));
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      break;
    }
    keep = !keep;
  }
  const double k = percentile(kept, 0.5), c = percentile(cold, 0.5);
  state.counters["vertices"] = n;
  state.counters["kept_p50_ms"] = k;
  state.counters["cold_p50_ms"] = c;
  state.counters["cold_over_kept"] = k > 0 ? c / k : 0;
}

// A session's first SetConstraints and first β > 0, with and without the background
// orders (background_orders.h): upload a capsule, let the user "think" until the background
// orders are done (with them off: as long as that took with them on, so both start from
// idle cores), then time SetConstraints and SetBeta(0.5). A fresh server per iteration,
// the two alternating.
void BM_OrdersAfterOpen(benchmark::State& state, int n) {
  const procedural::CapsuleCase capsule = procedural::capsule_case(n);
  const std::string ply = ply_bytes(capsule.mesh);
  std::vector<double> constrain_on, constrain_off, beta_on, beta_off, waited;
  bool background = true;
  double last_wait_ms = 0;
  for (auto _ : state) {
    Loopback lb("", background ? 1 : 0);
    pb::Session s;
    auto status = upload(*lb.stub, "capsule.ply", ply, &s);
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      break;
    }
    const auto t_wait = Clock::now();
    if (background) {
      for (;;) {
        const auto b = lb.server->background_orders();
        if (b.computed + b.failed + b.no_room + b.superseded >= 2 && !b.busy && b.queued == 0)
          break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      last_wait_ms = ms_since(t_wait);
      waited.push_back(last_wait_ms);
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(last_wait_ms));
    }
    auto t0 = Clock::now();
    status = constrain(*lb.stub, s.name(), capsule);
    (background ? constrain_on : constrain_off).push_back(ms_since(t0));
    grpc::ClientContext ctx;
    authorize(ctx);
    pb::SetBetaRequest req;
    req.set_name(s.name());
    req.mutable_beta()->set_value(0.5);
    pb::Session out;
    t0 = Clock::now();
    if (status.ok()) status = lb.stub->SetBeta(&ctx, req, &out);
    (background ? beta_on : beta_off).push_back(ms_since(t0));
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      break;
    }
    background = !background;
  }
  auto report = [&](const char* name, const std::vector<double>& on,
                    const std::vector<double>& off) {
    const double a = percentile(on, 0.5), b = percentile(off, 0.5);
    state.counters[std::string(name) + "_ms"] = b;            // the call computes its order
    state.counters[std::string(name) + "_ordered_ms"] = a;    // the background computed it
    state.counters[std::string(name) + "_ratio"] = b > 0 ? a / b : 0;
  };
  state.counters["vertices"] = n;
  report("constrain", constrain_on, constrain_off);
  report("beta_first", beta_on, beta_off);
  state.counters["background_ms"] = percentile(waited, 0.5);  // upload → both orders adopted
}

void register_all() {
  for (int n : g_smoke ? std::vector<int>{10000} : std::vector<int>{100000, 1000000})
    benchmark::RegisterBenchmark(("OrdersAfterOpen/" + std::to_string(n)).c_str(),
                                 BM_OrdersAfterOpen, n)
        ->Iterations(g_smoke ? 2 : (n >= 1000000 ? 4 : 6))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (int n : g_smoke ? std::vector<int>{10000} : std::vector<int>{100000, 1000000})
    benchmark::RegisterBenchmark(("Restore/" + std::to_string(n)).c_str(), BM_Restore, n)
        ->Iterations(g_smoke ? 2 : 6)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  struct Size {
    int n, unary, stream, bursts, memory_sessions;
  };
  const Size sizes[] = {{10000, 300, 300, 5, 8}, {100000, 60, 60, 3, 4}};
  for (const auto& s : sizes) {
    const std::string N = "/" + std::to_string(s.n);
    auto iters = [&](int k) { return g_smoke ? std::min(k, 5) : k; };
    benchmark::RegisterBenchmark(("Unary" + N).c_str(), BM_Unary, s.n, false,
                                 pb::FRAME_ENCODING_FLOAT32)
        ->Iterations(iters(s.unary))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("UnaryInProcess" + N).c_str(), BM_Unary, s.n, true,
                                 pb::FRAME_ENCODING_FLOAT32)
        ->Iterations(iters(s.unary))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    for (auto e : {pb::FRAME_ENCODING_QUANTIZED, pb::FRAME_ENCODING_MESHOPT})
      benchmark::RegisterBenchmark(("Unary" + N + "/" + encoding_name(e)).c_str(), BM_Unary, s.n,
                                   false, e)
          ->Iterations(iters(s.unary))
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    for (auto e : {pb::FRAME_ENCODING_FLOAT32, pb::FRAME_ENCODING_QUANTIZED,
                   pb::FRAME_ENCODING_MESHOPT})
      benchmark::RegisterBenchmark(("Encode" + N + "/" + encoding_name(e)).c_str(), BM_Encode,
                                   s.n, e)
          ->Iterations(iters(s.unary))
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    benchmark::RegisterBenchmark(("EncodeDelta" + N + "/apart:300").c_str(), BM_EncodeDelta, s.n, 300)
        ->Iterations(iters(s.unary))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("Stream" + N).c_str(), BM_Stream, s.n)
        ->Iterations(iters(s.stream))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    const int updates = g_smoke ? 20 : 200;
    benchmark::RegisterBenchmark(("Burst" + N + "/updates:" + std::to_string(updates)).c_str(),
                                 BM_Burst, s.n, updates, 0, pb::FRAME_ENCODING_FLOAT32)
        ->Iterations(g_smoke ? 1 : s.bursts)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(
        ("Drag" + N + "/hz:60/updates:" + std::to_string(updates)).c_str(), BM_Burst, s.n,
        updates, 16667, pb::FRAME_ENCODING_FLOAT32)
        ->Iterations(g_smoke ? 1 : 2)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    // At 20 Hz a move ends before the next update comes (no coalescing, no queue), so
    // over_p50_ms (latency − solve_ms) is what the stream, the encode and the client add.
    const int slow_updates = g_smoke ? 10 : 60;
    for (auto e : {pb::FRAME_ENCODING_FLOAT32, pb::FRAME_ENCODING_QUANTIZED,
                   pb::FRAME_ENCODING_MESHOPT})
      benchmark::RegisterBenchmark(("Drag" + N + "/hz:20/updates:" +
                                    std::to_string(slow_updates) + "/" + encoding_name(e))
                                       .c_str(),
                                   BM_Burst, s.n, slow_updates, 50000, e)
          ->Iterations(g_smoke ? 1 : 2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    for (bool distinct : {true, false}) {
      const int k = g_smoke ? 3 : (distinct ? s.memory_sessions : 4 * s.memory_sessions);
      benchmark::RegisterBenchmark(("Memory" + N + (distinct ? "/distinct" : "/shared") +
                                    "/sessions:" + std::to_string(k))
                                       .c_str(),
                                   BM_Memory, s.n, distinct, k)
          ->Iterations(1)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
}

std::string loadavg() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  f >> a >> b >> c;
  return a + " " + b + " " + c;
}

}  // namespace

int main(int argc, char** argv) {
  hdeform::ensure_process_environment(argv);  // as hdeform-server does
  std::vector<char*> args;
  constexpr std::string_view kStateFlag = "--hdeform_state_dir=";
  // As hdeform-server's --warm-cores-ms (0: the cores may halt between drag moves).
  constexpr std::string_view kWarmFlag = "--hdeform_warm_cores_ms=";
  for (int i = 0; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a.starts_with(kStateFlag))
      g_state_dir = std::string(a.substr(kStateFlag.size()));
    else if (a.starts_with(kWarmFlag)) {
      const std::string_view v = a.substr(kWarmFlag.size());
      int ms = -1;
      const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), ms);
      if (ec != std::errc() || end != v.data() + v.size() || ms < 0 || ms > 10000) {
        std::fprintf(stderr, "%.*s: expected milliseconds in 0..10000, got \"%.*s\"\n",
                     static_cast<int>(kWarmFlag.size() - 1), kWarmFlag.data(),
                     static_cast<int>(v.size()), v.data());
        return 2;
      }
      hdeform::WarmCores::instance().set_window(std::chrono::milliseconds(ms));
    } else
      args.push_back(argv[i]);
  }
  int nargs = static_cast<int>(args.size());
  if (!bench::initialize(nargs, args.data(), g_smoke)) return 1;
  spdlog::set_level(spdlog::level::warn);
  register_all();
  benchmark::AddCustomContext("loadavg_start", loadavg());
  benchmark::AddCustomContext("state", g_state_dir.empty() ? "memory" : "sqlite:" + g_state_dir);
  g_main = std::make_unique<Loopback>();
  benchmark::RunSpecifiedBenchmarks();
  g_cases.clear();
  g_in_process_stub.reset();
  g_main.reset();
  std::fprintf(stderr, "load average at the end: %s\n", loadavg().c_str());
  benchmark::Shutdown();
  return 0;
}
