#include "common.h"

#include "mesh_check.h"
#include "progress.h"

#if HDEFORM_CLI_IN_PROCESS
#include "service/rpc/server.h"
#endif

#include <spdlog/spdlog.h>

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <set>
#include <sstream>
#include <thread>

namespace hdeform::cli {

namespace fs = std::filesystem;

const char* status_code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

namespace {
std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}
}  // namespace

RpcError::RpcError(const std::string& rpc, const grpc::Status& status)
    : CliError(rpc + ": " + status_code_name(status.error_code()) + ": " +
               one_line(status.error_message())),
      code(status.error_code()) {}

// ---------------------------------------------------------------------------------------
// Connection

void check_token(const std::string& token) {
  // A metadata value the server can take as one token: printable ASCII without spaces or
  // commas (the server splits joined headers at commas), at most 256 characters.
  if (token.size() > 256) throw CliError("--token: longer than 256 characters");
  for (unsigned char c : token)
    if (c <= 0x20 || c >= 0x7f || c == ',')
      throw CliError("--token: not a token (give the token itself: printable characters, no "
                     "spaces, no commas, no 'Bearer ' prefix)");
}

namespace {

constexpr auto kRetryPause = std::chrono::milliseconds(200);

std::chrono::system_clock::time_point deadline_in(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::milliseconds(static_cast<long>(seconds * 1000));
}

// Whether something accepts TCP connections at HOST:PORT (when a gRPC connection failed:
// a listener there means the handshake failed, e.g. plain text against a TLS server).
bool tcp_listener_at(const std::string& target) {
  std::string host, port;
  if (!target.empty() && target.front() == '[') {
    const auto close = target.find(']');
    if (close == std::string::npos || close + 1 >= target.size() || target[close + 1] != ':')
      return false;
    host = target.substr(1, close - 1);
    port = target.substr(close + 2);
  } else {
    const auto colon = target.rfind(':');
    if (colon == std::string::npos || target.find(':') != colon) return false;  // no scheme
    host = target.substr(0, colon);
    port = target.substr(colon + 1);
  }
  if (host.empty() || port.empty()) return false;
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  if (::getaddrinfo(host.c_str(), port.c_str(), &hints, &res) != 0) return false;
  bool ok = false;
  for (addrinfo* a = res; a && !ok; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    ok = ::connect(fd, a->ai_addr, a->ai_addrlen) == 0;
    ::close(fd);
  }
  ::freeaddrinfo(res);
  return ok;
}

}  // namespace

Connection::Connection(const GlobalOptions& options) : options_(options) {
  if (!options_.token.empty()) check_token(options_.token);
  if (!options_.server.empty()) {
    remote_ = true;
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);  // frames of big meshes exceed gRPC's 4 MiB default
    args.SetMaxSendMessageSize(-1);
    // After a server restart, reconnect within a fraction of a second (gRPC's default first
    // backoff is 1 s, growing to 120 s): the retry below waits for it.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
    std::shared_ptr<grpc::ChannelCredentials> creds;
    const bool tls = !options_.tls_ca.empty();
    if (tls) {
      grpc::SslCredentialsOptions ssl;
      ssl.pem_root_certs = read_file(options_.tls_ca);
      if (!options_.tls_cert.empty()) {
        ssl.pem_cert_chain = read_file(options_.tls_cert);
        ssl.pem_private_key = read_file(options_.tls_key);
      }
      creds = grpc::SslCredentials(ssl);
    } else {
      creds = grpc::InsecureChannelCredentials();
    }
    channel_ = grpc::CreateCustomChannel(options_.server, creds, args);
    const auto deadline = deadline_in(options_.connect_timeout_s);
    auto cannot = [&](const std::string& why) {
      std::string msg = "cannot connect to hdeform-server at " + options_.server;
      if (tls) msg += " over TLS";
      msg += why;
      // Something listens there, but the gRPC connection failed: a TLS mismatch.
      if (why.empty() && tcp_listener_at(options_.server))
        msg += tls ? " (the TLS handshake failed: does the server use TLS, was its certificate "
                     "for this host name signed by --tls-ca, does it require a client "
                     "certificate (--tls-cert/--tls-key)?)"
                   : " (the server accepts connections but the handshake failed: if it uses "
                     "TLS, pass --tls-ca)";
      return CliError(msg);
    };
    // Fail fast when the connection is refused; wait up to the deadline otherwise. A first
    // failed attempt while something listens there is tried once more (after the 100 ms
    // reconnect backoff): on a loaded machine a connection right after another client's
    // can fail once (seen in tests/cli: ≈ 1 in 30 quick successive runs); a TLS mismatch
    // fails again and is reported below.
    // The second attempt gets 2 s: a handshake that failed once fails again at once or hangs.
    auto wait_until = deadline;
    bool retried = false;
    for (auto state = channel_->GetState(true); state != GRPC_CHANNEL_READY;
         state = channel_->GetState(true)) {
      if (state == GRPC_CHANNEL_SHUTDOWN) throw cannot("");
      if (state == GRPC_CHANNEL_TRANSIENT_FAILURE) {
        if (retried || !tcp_listener_at(options_.server)) throw cannot("");
        retried = true;
        wait_until = std::min(deadline, deadline_in(2.0));
        spdlog::debug("the first connection attempt failed; trying once more");
      }
      if (!channel_->WaitForStateChange(state, wait_until))
        throw cannot(retried ? "" : " (timed out)");
    }
    spdlog::debug("connected to {}{}", options_.server, tls ? " (TLS)" : "");
  } else {
    if (!options_.tls_ca.empty())
      spdlog::debug("--tls-ca: no effect without --server (the in-process service)");
#if HDEFORM_CLI_IN_PROCESS
    service::ServerOptions so;  // the defaults: no durable state, no TLS, no operator token
    so.listen_address = "";
    // A batch job computes its orders when it needs them; one in the background would only
    // delay the job's exit (a stop waits for the order in progress).
    so.background_order_from = 0;
    // It sets constraints right after the open: the mesh's order is computed beside its
    // operators, where one core would otherwise idle (ServerOptions::order_on_open).
    so.order_on_open = true;
    server_ = std::make_shared<service::Server>(so);
    channel_ = server_->in_process_channel();
    spdlog::debug("started the in-process service");
#else
    throw CliError(
        "this hdeform was built without the in-process service: pass --server HOST:PORT");
#endif
  }
  stub_ = pb::Deformation::NewStub(channel_);
}

Connection::~Connection() {
  stub_.reset();
  channel_.reset();
#if HDEFORM_CLI_IN_PROCESS
  if (server_) server_->shutdown();
#endif
  server_.reset();
}

void Connection::remember_tokens(const pb::Session& session) {
  if (session.edit_token().empty() && session.view_token().empty()) return;
  jar_[session_id_of(session.name())] = {session.edit_token(), session.view_token()};
}

const SessionTokens* Connection::tokens_for(const std::string& session_id) const {
  const auto it = jar_.find(session_id_of(session_id));
  return it == jar_.end() ? nullptr : &it->second;
}

void Connection::prepare(grpc::ClientContext& ctx, const std::string& route_key,
                         double timeout_s, TokenScope scope,
                         const std::string& session_id) const {
  if (!route_key.empty()) ctx.AddMetadata("x-session-id", route_key);
  std::set<std::string> tokens;  // each once
  if (scope == TokenScope::kSession) {
    const auto* own = tokens_for(session_id.empty() ? route_key : session_id);
    if (own) tokens.insert(!own->edit.empty() ? own->edit : own->view);
  } else if (scope == TokenScope::kAll) {
    for (const auto& [id, t] : jar_) {
      if (!t.edit.empty()) tokens.insert(t.edit);
      else if (!t.view.empty()) tokens.insert(t.view);
    }
  }
  if (scope != TokenScope::kNone && !options_.token.empty()) tokens.insert(options_.token);
  // One entry, comma-separated: nginx refuses a request with two Authorization headers (400).
  std::string value;
  for (const auto& t : tokens) value += (value.empty() ? "Bearer " : ", Bearer ") + t;
  if (!value.empty()) ctx.AddMetadata("authorization", value);
  if (timeout_s > 0) ctx.set_deadline(deadline_in(timeout_s));
}

bool Connection::wait_before_retry(const char* what) {
  spdlog::info("{}: the server is unavailable; retrying once in {} ms", what,
               kRetryPause.count());
  std::this_thread::sleep_for(kRetryPause);
  const bool ready = channel_->WaitForConnected(deadline_in(options_.connect_timeout_s));
  if (!ready) spdlog::info("{}: the server is still unavailable", what);
  return ready;
}

grpc::Status Connection::call(const char* rpc,
                              const std::function<void(grpc::ClientContext&)>& setup,
                              const Attempt& attempt, bool retry) {
  grpc::Status status;
  {
    grpc::ClientContext ctx;
    setup(ctx);
    status = attempt(ctx);
  }
  if (status.error_code() != grpc::StatusCode::UNAVAILABLE || !retry || !remote_) return status;
  wait_before_retry(rpc);
  grpc::ClientContext ctx;
  setup(ctx);
  status = attempt(ctx);
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE)
    return grpc::Status(status.error_code(), status.error_message() + " (retried once)");
  return status;
}

std::string session_id_of(const std::string& name) {
  constexpr std::string_view prefix = "sessions/";
  if (name.compare(0, prefix.size(), prefix) == 0) return name.substr(prefix.size());
  return name;
}

std::string session_name_of(const std::string& id_or_name) {
  return "sessions/" + session_id_of(id_or_name);
}

std::string random_id() {
  std::random_device rd;
  std::mt19937_64 gen((static_cast<std::uint64_t>(rd()) << 32) ^ rd() ^
                      static_cast<std::uint64_t>(
                          std::chrono::steady_clock::now().time_since_epoch().count()));
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(gen()));
  return buf;
}

// ---------------------------------------------------------------------------------------
// SessionClient

SessionClient::SessionClient(Connection& conn, std::string name)
    : conn_(&conn), name_(session_name_of(name)), key_(session_id_of(name)) {}

SessionClient::SessionClient(Connection& conn, std::string name, std::string key,
                             pb::Session info)
    : conn_(&conn), name_(std::move(name)), key_(std::move(key)), info_(std::move(info)) {}

void SessionClient::call(const char* rpc, const Connection::Attempt& attempt, double timeout_s,
                         const std::string& doing) {
  Activity activity(doing.empty() ? std::string(rpc) : std::string(rpc) + ": " + doing);
  const std::string id = session_id_of(name_);
  grpc::Status status = conn_->call(
      rpc,
      [&](grpc::ClientContext& ctx) {
        conn_->prepare(ctx, key_, timeout_s, TokenScope::kSession, id);
      },
      attempt);
  if (!status.ok()) throw RpcError(rpc, status);
}

namespace {
// "12.5": bytes in MiB with one decimal.
std::string mib_text(std::size_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", static_cast<double>(bytes) / (1u << 20));
  return buf;
}
}  // namespace

// Not retried: a CreateSession that reached the server before it died may have created the
// session, and its tokens are answered only once.
SessionClient SessionClient::create(Connection& conn, const std::string& mesh,
                                    const pb::MeshRepair* repair) {
  const std::string id = random_id();
  pb::CreateSessionRequest header_msg;
  auto* header = header_msg.mutable_header();
  header->set_session_id(id);

  std::string bytes;
  std::error_code ec;
  if (fs::is_regular_file(mesh, ec)) {
    bytes = read_file(mesh);
    header->set_filename(fs::path(mesh).filename().string());
    header->set_total_bytes(static_cast<std::int64_t>(bytes.size()));
  } else if (mesh.find('/') != std::string::npos || fs::path(mesh).has_extension()) {
    throw CliError(mesh + ": no such file");
  } else {
    header->set_library_mesh(mesh);
  }
  if (repair) *header->mutable_repair() = *repair;

  grpc::ClientContext ctx;
  conn.prepare(ctx, id, conn.options().call_timeout_s, TokenScope::kNone);
  pb::Session session;
  Activity activity(bytes.empty() ? "CreateSession: loading " + mesh
                                  : "uploading " + header->filename());
  auto writer = conn.stub().CreateSession(&ctx, &session);
  bool ok = writer->Write(header_msg);
  constexpr std::size_t kChunk = 1u << 20;  // 1 MiB
  for (std::size_t at = 0; ok && at < bytes.size(); at += kChunk) {
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(bytes.substr(at, kChunk));
    ok = writer->Write(chunk);
    activity.set("uploading " + header->filename() + ": " +
                 mib_text(std::min(at + kChunk, bytes.size())) + " of " + mib_text(bytes.size()) +
                 " MiB");
  }
  writer->WritesDone();
  if (!bytes.empty()) activity.set("CreateSession: the server reads " + header->filename());
  grpc::Status status = writer->Finish();
  if (!status.ok()) {
    // The refusals for defects repair_mesh fixes.
    const std::string& m = status.error_message();
    if (!repair && !bytes.empty() && status.error_code() == grpc::StatusCode::INVALID_ARGUMENT &&
        (m.rfind("zero-area triangles", 0) == 0 || m.rfind("duplicate triangles", 0) == 0 ||
         m.rfind("non-manifold vertex", 0) == 0))
      status = grpc::Status(status.error_code(), m + " (--repair may fix it)");
    throw RpcError("CreateSession", status);
  }
  // The routing key stays the id we proposed: should a server pick another id (an old server
  // that ignores session_id), the proposed key still routes to the replica that holds it.
  if (session_id_of(session.name()) != id)
    spdlog::debug("server named the session {} (proposed {})", session.name(), id);
  spdlog::info("created {} ({} vertices, {} triangles)", session.name(), session.vertex_count(),
               session.triangle_count());
  if (repair) {
    if (session.repair().lines_size() == 0)
      std::cerr << "hdeform: repair of " << header->filename() << ": nothing to repair\n";
    for (const auto& line : session.repair().lines())
      std::cerr << "hdeform: repair of " << header->filename() << ": " << line << "\n";
  }
  conn.remember_tokens(session);
  session.clear_edit_token();  // kept in the jar only
  session.clear_view_token();
  return SessionClient(conn, session.name(), id, session);
}

SessionClient SessionClient::import(Connection& conn, const pb::Snapshot& snapshot) {
  return import(conn, snapshot, random_id());
}

// Not retried (as CreateSession). Presents every token known: a snapshot that names its mesh
// by hash alone needs the edit token of a live session on that mesh.
SessionClient SessionClient::import(Connection& conn, const pb::Snapshot& snapshot,
                                    const std::string& session_id) {
  const std::string key = session_id_of(session_id);
  grpc::ClientContext ctx;
  conn.prepare(ctx, key, conn.options().call_timeout_s, TokenScope::kAll);
  pb::ImportSessionRequest req;
  *req.mutable_snapshot() = snapshot;
  req.set_session_id(key);
  pb::Session session;
  grpc::Status status = conn.stub().ImportSession(&ctx, req, &session);
  if (!status.ok()) throw RpcError("ImportSession", status);
  conn.remember_tokens(session);
  session.clear_edit_token();
  session.clear_view_token();
  return SessionClient(conn, session.name(), key, session);
}

pb::Session SessionClient::get() {
  pb::GetSessionRequest req;
  req.set_name(name_);
  pb::Session s;
  call("GetSession", [&](grpc::ClientContext& ctx) {
    return conn_->stub().GetSession(&ctx, req, &s);
  }, timeout());
  info_ = s;
  return s;
}

pb::Session SessionClient::set_constraints(const pb::Constraints& constraints) {
  pb::SetConstraintsRequest req;
  req.set_name(name_);
  req.set_request_id(random_id());  // a retry (UNAVAILABLE) is answered, not applied twice
  *req.mutable_constraints() = constraints;
  pb::Session s;
  call("SetConstraints", [&](grpc::ClientContext& ctx) {
    return conn_->stub().SetConstraints(&ctx, req, &s);
  }, timeout(), "analysing and factorizing");
  info_ = s;
  return s;
}

pb::Session SessionClient::set_beta(double value, pb::BetaUnits units) {
  pb::Beta beta;
  beta.set_value(value);
  beta.set_units(units);
  return set_beta(beta);
}

pb::Session SessionClient::set_beta(const pb::Beta& beta) {
  pb::SetBetaRequest req;
  req.set_name(name_);
  req.set_request_id(random_id());  // a retry (UNAVAILABLE) is answered, not applied twice
  *req.mutable_beta() = beta;
  pb::Session s;
  call("SetBeta", [&](grpc::ClientContext& ctx) {
    return conn_->stub().SetBeta(&ctx, req, &s);
  }, timeout(), beta.automatic() ? "picking beta automatically (a factorization per sample)"
                                 : "factorizing");
  info_ = s;
  return s;
}

pb::Frame SessionClient::update(const std::vector<pb::HandleTransform>& transforms,
                                std::int64_t sequence, bool energies) {
  pb::UpdateHandlesRequest req;
  req.set_name(name_);
  req.set_sequence(sequence);
  req.set_energies(energies);
  for (const auto& t : transforms) *req.add_transforms() = t;
  pb::Frame frame;
  // Absolute transforms: solving them twice leaves the same pose.
  call("UpdateHandles", [&](grpc::ClientContext& ctx) {
    return conn_->stub().UpdateHandles(&ctx, req, &frame);
  }, timeout(), "solving");
  return frame;
}

pb::Frame SessionClient::deform(const std::vector<pb::HandleTransform>& transforms,
                                std::int64_t sequence, const pb::Beta& beta, bool energies) {
  pb::DeformRequest req;
  req.set_name(name_);
  req.set_sequence(sequence);
  req.set_energies(energies);
  for (const auto& t : transforms) *req.add_transforms() = t;
  *req.mutable_beta() = beta;
  pb::Frame frame;
  bool any = false;
  // The stream is reopened once (and the message sent again) if it fails with UNAVAILABLE.
  call("Deform", [&](grpc::ClientContext& ctx) {
    auto stream = conn_->stub().Deform(&ctx);
    stream->Write(req);
    stream->WritesDone();
    pb::Frame got;
    any = false;
    while (stream->Read(&got)) {
      frame.Swap(&got);
      any = true;
    }
    return stream->Finish();
  }, timeout(), beta.automatic() ? "picking beta automatically (a factorization per sample)"
                                 : "solving");
  if (!any) throw CliError("Deform: the server sent no frame");
  return frame;
}

pb::SweepResponse SessionClient::sweep(const std::vector<double>& betas, pb::BetaUnits units,
                                       const std::vector<pb::HandleTransform>& transforms) {
  pb::SweepRequest req;
  req.set_name(name_);
  for (double b : betas) req.add_betas(b);
  req.set_units(units);
  for (const auto& t : transforms) *req.add_transforms() = t;
  pb::SweepResponse resp;
  call("Sweep", [&](grpc::ClientContext& ctx) {
    resp.Clear();
    return conn_->stub().Sweep(&ctx, req, &resp);
  }, timeout(), std::to_string(betas.size()) + " beta value(s), a factorization each");
  return resp;
}

std::size_t SessionClient::download(const std::string& path, pb::MeshFormat format, bool rest,
                                    const MeshOutputOptions& options) {
  pb::GetMeshRequest req;
  req.set_name(name_);
  req.set_rest(rest);
  req.set_format(format);
  req.set_up(options.up);
  req.set_ply_encoding(options.ply);
  req.set_glb_compression(options.glb_compression);
  std::string bytes;
  // A download cut by UNAVAILABLE starts again from its first chunk.
  call("GetMesh", [&](grpc::ClientContext& ctx) {
    bytes.clear();
    auto reader = conn_->stub().GetMesh(&ctx, req);
    pb::MeshChunk chunk;
    while (reader->Read(&chunk)) {
      if (bytes.empty() && chunk.total_bytes() > 0)
        bytes.reserve(static_cast<std::size_t>(chunk.total_bytes()));
      bytes += chunk.data();
    }
    return reader->Finish();
  }, timeout(), "downloading the mesh");
  const auto bad = count_non_finite_coordinates(bytes, mesh_format_extension(format));
  if (bad && *bad > 0)
    throw CliError(path + ": not written: the mesh from the server has " +
                   std::to_string(*bad) + " non-finite (NaN/Inf) vertex coordinates");
  write_file(path, bytes);
  return bytes.size();
}

pb::Snapshot SessionClient::export_snapshot(bool include_mesh) {
  pb::ExportSessionRequest req;
  req.set_name(name_);
  req.set_include_mesh(include_mesh);
  pb::Snapshot snap;
  call("ExportSession", [&](grpc::ClientContext& ctx) {
    return conn_->stub().ExportSession(&ctx, req, &snap);
  }, timeout());
  return snap;
}

pb::Timeline SessionClient::set_timeline(const pb::Timeline& timeline) {
  pb::SetTimelineRequest req;
  req.set_name(name_);
  req.set_request_id(random_id());  // a retry (UNAVAILABLE) is answered, not applied twice
  *req.mutable_timeline() = timeline;
  pb::Timeline out;
  call("SetTimeline", [&](grpc::ClientContext& ctx) {
    return conn_->stub().SetTimeline(&ctx, req, &out);
  }, timeout());
  return out;
}

std::size_t SessionClient::export_animation(const std::string& path,
                                            const pb::ExportAnimationRequest& request) {
  pb::ExportAnimationRequest req = request;
  req.set_name(name_);
  std::string bytes;
  call("ExportAnimation", [&](grpc::ClientContext& ctx) {
    bytes.clear();
    auto reader = conn_->stub().ExportAnimation(&ctx, req);
    pb::MeshChunk chunk;
    while (reader->Read(&chunk)) bytes += chunk.data();
    return reader->Finish();
  }, timeout(), "solving and writing the animation");
  write_file(path, bytes);
  return bytes.size();
}

pb::RigReport SessionClient::export_rig(const std::string& path, const pb::ExportRigRequest& request,
                                        std::size_t* size) {
  pb::ExportRigRequest req = request;
  req.set_name(name_);
  std::string bytes;
  pb::RigReport report;
  call("ExportRig", [&](grpc::ClientContext& ctx) {
    bytes.clear();
    auto reader = conn_->stub().ExportRig(&ctx, req);
    pb::MeshChunk chunk;
    while (reader->Read(&chunk)) {
      if (chunk.has_rig_report()) report = chunk.rig_report();
      bytes += chunk.data();
    }
    return reader->Finish();
  }, timeout(), "solving each pose and writing the rig");
  write_file(path, bytes);
  if (size) *size = bytes.size();
  return report;
}

void SessionClient::remove() {
  pb::DeleteSessionRequest req;
  req.set_name(name_);
  pb::DeleteSessionResponse resp;
  int attempts = 0;
  call("DeleteSession", [&](grpc::ClientContext& ctx) {
    grpc::Status status = conn_->stub().DeleteSession(&ctx, req, &resp);
    // A retry that finds the session gone: the first attempt deleted it.
    if (++attempts > 1 && status.error_code() == grpc::StatusCode::NOT_FOUND)
      return grpc::Status::OK;
    return status;
  }, timeout());
}

std::vector<pb::Session> list_sessions(Connection& conn) {
  pb::ListSessionsRequest req;
  pb::ListSessionsResponse resp;
  grpc::Status status = conn.call(
      "ListSessions",
      [&](grpc::ClientContext& ctx) {
        conn.prepare(ctx, "", conn.options().call_timeout_s, TokenScope::kAll);
      },
      [&](grpc::ClientContext& ctx) {
        resp.Clear();
        return conn.stub().ListSessions(&ctx, req, &resp);
      });
  if (!status.ok()) throw RpcError("ListSessions", status);
  return {resp.sessions().begin(), resp.sessions().end()};
}

void check_frame_finite(const pb::Frame& frame, const std::string& what) {
  const std::size_t bad = count_non_finite_floats(frame.positions());
  if (bad > 0)
    throw CliError(what + ": the deformed mesh has " + std::to_string(bad) +
                   " non-finite (NaN/Inf) vertex coordinates; no file written");
}

// ---------------------------------------------------------------------------------------
// Files and small parsers

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CliError(path + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw CliError(path + ": read error");
  return ss.str();
}

void write_file(const std::string& path, const std::string& bytes) {
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw CliError(path + ": cannot open for writing");
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) throw CliError(path + ": write error");
}

pb::MeshFormat mesh_format_for(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".glb") return pb::MESH_FORMAT_GLB;
  if (ext == ".obj") return pb::MESH_FORMAT_OBJ;
  if (ext == ".off") return pb::MESH_FORMAT_OFF;
  if (ext == ".ply") return pb::MESH_FORMAT_PLY;
  throw CliError(path + ": unsupported output format '" + ext +
                 "' (use .glb, .obj, .off or .ply)");
}

std::string mesh_format_extension(pb::MeshFormat format) {
  switch (format) {
    case pb::MESH_FORMAT_OBJ: return "obj";
    case pb::MESH_FORMAT_OFF: return "off";
    case pb::MESH_FORMAT_PLY: return "ply";
    default: return "glb";
  }
}

pb::BetaUnits parse_beta_units(const std::string& text) {
  if (text == "area") return pb::BETA_UNITS_AREA;
  if (text == "raw") return pb::BETA_UNITS_RAW;
  throw CliError("beta units '" + text + "': expected 'area' or 'raw'");
}

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace hdeform::cli
