#include "common.h"

#include "mesh_check.h"

#if HDEFORM_CLI_IN_PROCESS
#include "service/server.h"
#endif

#include <spdlog/spdlog.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

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

Connection::Connection(const GlobalOptions& options) : options_(options) {
  if (!options_.server.empty()) {
    remote_ = true;
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);  // frames of big meshes exceed gRPC's 4 MiB default
    args.SetMaxSendMessageSize(-1);
    channel_ = grpc::CreateCustomChannel(options_.server, grpc::InsecureChannelCredentials(),
                                         args);
    auto deadline = std::chrono::system_clock::now() +
                    std::chrono::milliseconds(static_cast<long>(options_.connect_timeout_s * 1000));
    // Fail fast when the connection is refused; wait up to the deadline otherwise.
    for (auto state = channel_->GetState(true); state != GRPC_CHANNEL_READY;
         state = channel_->GetState(true)) {
      if (state == GRPC_CHANNEL_TRANSIENT_FAILURE || state == GRPC_CHANNEL_SHUTDOWN)
        throw CliError("cannot connect to hdeform-server at " + options_.server);
      if (!channel_->WaitForStateChange(state, deadline))
        throw CliError("cannot connect to hdeform-server at " + options_.server + " (timed out)");
    }
    spdlog::debug("connected to {}", options_.server);
  } else {
#if HDEFORM_CLI_IN_PROCESS
    service::ServerOptions so;
    so.listen_address = "";
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

void prepare(grpc::ClientContext& ctx, const std::string& route_key, double timeout_s) {
  if (!route_key.empty()) ctx.AddMetadata("x-session-id", route_key);
  if (timeout_s > 0)
    ctx.set_deadline(std::chrono::system_clock::now() +
                     std::chrono::milliseconds(static_cast<long>(timeout_s * 1000)));
}

std::string session_id_of(const std::string& name) {
  constexpr std::string_view prefix = "sessions/";
  if (name.compare(0, prefix.size(), prefix) == 0) return name.substr(prefix.size());
  return name;
}

std::string session_name_of(const std::string& id_or_name) {
  return "sessions/" + session_id_of(id_or_name);
}

std::string random_session_id() {
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

SessionClient SessionClient::create(Connection& conn, const std::string& mesh) {
  const std::string id = random_session_id();
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

  grpc::ClientContext ctx;
  prepare(ctx, id, conn.options().call_timeout_s);
  pb::Session session;
  auto writer = conn.stub().CreateSession(&ctx, &session);
  bool ok = writer->Write(header_msg);
  constexpr std::size_t kChunk = 1u << 20;  // 1 MiB
  for (std::size_t at = 0; ok && at < bytes.size(); at += kChunk) {
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(bytes.substr(at, kChunk));
    ok = writer->Write(chunk);
  }
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  if (!status.ok()) throw RpcError("CreateSession", status);
  // The routing key stays the id we proposed: should a server pick another id (an old server
  // that ignores session_id), the proposed key still routes to the replica that holds it.
  if (session_id_of(session.name()) != id)
    spdlog::debug("server named the session {} (proposed {})", session.name(), id);
  spdlog::info("created {} ({} vertices, {} triangles)", session.name(), session.vertex_count(),
               session.triangle_count());
  return SessionClient(conn, session.name(), id, session);
}

SessionClient SessionClient::import(Connection& conn, const pb::Snapshot& snapshot) {
  return import(conn, snapshot, random_session_id());
}

SessionClient SessionClient::import(Connection& conn, const pb::Snapshot& snapshot,
                                    const std::string& session_id) {
  const std::string key = session_id_of(session_id);
  grpc::ClientContext ctx;
  prepare(ctx, key, conn.options().call_timeout_s);
  pb::ImportSessionRequest req;
  *req.mutable_snapshot() = snapshot;
  req.set_session_id(key);
  pb::Session session;
  grpc::Status status = conn.stub().ImportSession(&ctx, req, &session);
  if (!status.ok()) throw RpcError("ImportSession", status);
  return SessionClient(conn, session.name(), key, session);
}

pb::Session SessionClient::get() {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::GetSessionRequest req;
  req.set_name(name_);
  pb::Session s;
  grpc::Status status = conn_->stub().GetSession(&ctx, req, &s);
  if (!status.ok()) throw RpcError("GetSession", status);
  info_ = s;
  return s;
}

pb::Session SessionClient::set_constraints(const pb::Constraints& constraints) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::SetConstraintsRequest req;
  req.set_name(name_);
  *req.mutable_constraints() = constraints;
  pb::Session s;
  grpc::Status status = conn_->stub().SetConstraints(&ctx, req, &s);
  if (!status.ok()) throw RpcError("SetConstraints", status);
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
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::SetBetaRequest req;
  req.set_name(name_);
  *req.mutable_beta() = beta;
  pb::Session s;
  grpc::Status status = conn_->stub().SetBeta(&ctx, req, &s);
  if (!status.ok()) throw RpcError("SetBeta", status);
  info_ = s;
  return s;
}

pb::Frame SessionClient::update(const std::vector<pb::HandleTransform>& transforms,
                                std::int64_t sequence, bool energies) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::UpdateHandlesRequest req;
  req.set_name(name_);
  req.set_sequence(sequence);
  req.set_energies(energies);
  for (const auto& t : transforms) *req.add_transforms() = t;
  pb::Frame frame;
  grpc::Status status = conn_->stub().UpdateHandles(&ctx, req, &frame);
  if (!status.ok()) throw RpcError("UpdateHandles", status);
  return frame;
}

pb::Frame SessionClient::deform(const std::vector<pb::HandleTransform>& transforms,
                                std::int64_t sequence, const pb::Beta& beta, bool energies) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  auto stream = conn_->stub().Deform(&ctx);
  pb::DeformRequest req;
  req.set_name(name_);
  req.set_sequence(sequence);
  req.set_energies(energies);
  for (const auto& t : transforms) *req.add_transforms() = t;
  *req.mutable_beta() = beta;
  stream->Write(req);
  stream->WritesDone();
  pb::Frame frame, got;
  bool any = false;
  while (stream->Read(&got)) {
    frame.Swap(&got);
    any = true;
  }
  grpc::Status status = stream->Finish();
  if (!status.ok()) throw RpcError("Deform", status);
  if (!any) throw CliError("Deform: the server sent no frame");
  return frame;
}

pb::SweepResponse SessionClient::sweep(const std::vector<double>& betas, pb::BetaUnits units,
                                       const std::vector<pb::HandleTransform>& transforms) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::SweepRequest req;
  req.set_name(name_);
  for (double b : betas) req.add_betas(b);
  req.set_units(units);
  for (const auto& t : transforms) *req.add_transforms() = t;
  pb::SweepResponse resp;
  grpc::Status status = conn_->stub().Sweep(&ctx, req, &resp);
  if (!status.ok()) throw RpcError("Sweep", status);
  return resp;
}

std::size_t SessionClient::download(const std::string& path, pb::MeshFormat format, bool rest) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::GetMeshRequest req;
  req.set_name(name_);
  req.set_rest(rest);
  req.set_format(format);
  auto reader = conn_->stub().GetMesh(&ctx, req);
  std::string bytes;
  pb::MeshChunk chunk;
  while (reader->Read(&chunk)) {
    if (bytes.empty() && chunk.total_bytes() > 0)
      bytes.reserve(static_cast<std::size_t>(chunk.total_bytes()));
    bytes += chunk.data();
  }
  grpc::Status status = reader->Finish();
  if (!status.ok()) throw RpcError("GetMesh", status);
  const auto bad = count_non_finite_coordinates(bytes, mesh_format_extension(format));
  if (bad && *bad > 0)
    throw CliError(path + ": not written: the mesh from the server has " +
                   std::to_string(*bad) + " non-finite (NaN/Inf) vertex coordinates");
  write_file(path, bytes);
  return bytes.size();
}

pb::Snapshot SessionClient::export_snapshot(bool include_mesh) {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::ExportSessionRequest req;
  req.set_name(name_);
  req.set_include_mesh(include_mesh);
  pb::Snapshot snap;
  grpc::Status status = conn_->stub().ExportSession(&ctx, req, &snap);
  if (!status.ok()) throw RpcError("ExportSession", status);
  return snap;
}

void SessionClient::remove() {
  grpc::ClientContext ctx;
  prepare(ctx, key_, timeout());
  pb::DeleteSessionRequest req;
  req.set_name(name_);
  pb::DeleteSessionResponse resp;
  grpc::Status status = conn_->stub().DeleteSession(&ctx, req, &resp);
  if (!status.ok()) throw RpcError("DeleteSession", status);
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
