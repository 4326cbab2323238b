// Shared pieces of the hdeform CLI: errors, the connection (remote or in-process, plain or
// TLS) with its token jar and retry policy, and a small session client that adds the
// x-session-id routing header and the session's capability token to every call.
#pragma once

#include "errors.h"
#include "hdeform/v1/deform.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace hdeform::service {
class Server;
}

namespace hdeform::cli {

namespace pb = ::hdeform::v1;

// "RPC: CODE: server message".
struct RpcError : CliError {
  RpcError(const std::string& rpc, const grpc::Status& status);
  grpc::StatusCode code;
};

const char* status_code_name(grpc::StatusCode code);

// How written meshes look beyond their format (deform -o, run outputs): --up, --ply.
struct MeshOutputOptions {
  pb::UpAxis up = pb::UP_AXIS_Y;
  pb::PlyEncoding ply = pb::PLY_ENCODING_AS_INPUT;
  pb::GlbCompression glb_compression = pb::GLB_COMPRESSION_NONE;
};

struct GlobalOptions {
  std::string server;            // HOST:PORT; empty = in-process service
  std::string log_level = "warn";
  double connect_timeout_s = 10;
  double call_timeout_s = 600;   // per unary call (a factorization of a big mesh takes a while)
  // --token / HDEFORM_TOKEN: a session's edit or view token (or the operator token), sent as
  // `authorization: Bearer TOKEN`. Secret: never logged or printed.
  std::string token;
  // --tls-ca turns TLS on (root CA, PEM); --tls-cert/--tls-key: a client certificate.
  std::string tls_ca, tls_cert, tls_key;
};

// Throws CliError (never naming the token's text) when --token is not a plain token.
void check_token(const std::string& token);

// The two tokens of a session (Session.edit_token / view_token).
struct SessionTokens {
  std::string edit, view;
};

// Which tokens a call presents: none (CreateSession), those for its session (its own from
// the jar, and --token), or every token known (ListSessions, ImportSession).
enum class TokenScope { kNone, kSession, kAll };

// A channel to hdeform-server: remote (--server) or an in-process Server.
class Connection {
 public:
  explicit Connection(const GlobalOptions& options);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  pb::Deformation::Stub& stub() { return *stub_; }
  bool remote() const { return remote_; }
  const GlobalOptions& options() const { return options_; }

  // The token jar: the tokens of the sessions this run created (CreateSession/ImportSession
  // answers), by session id.
  void remember_tokens(const pb::Session& session);
  const SessionTokens* tokens_for(const std::string& session_id) const;

  // Prepares one attempt of a call: the x-session-id routing header (when `route_key` is
  // set), `authorization: Bearer …` entries as `scope` says (kSession: the jar's edit token
  // of `session_id`, and --token) and a deadline (none when timeout_s <= 0).
  void prepare(grpc::ClientContext& ctx, const std::string& route_key, double timeout_s,
               TokenScope scope = TokenScope::kSession, const std::string& session_id = "") const;

  // The retry policy (docs/cli.md "Retries"): runs `attempt` with a fresh context; when a
  // remote call fails with UNAVAILABLE and `retry` is set, waits 200 ms and for the channel to
  // reconnect (up to the connect timeout), then runs it once more.
  using Attempt = std::function<grpc::Status(grpc::ClientContext&)>;
  grpc::Status call(const char* rpc, const std::function<void(grpc::ClientContext&)>& setup,
                    const Attempt& attempt, bool retry = true);
  // The pause before a retry: 200 ms, then waits up to the connect timeout for the channel to
  // be ready again. False when it is not.
  bool wait_before_retry(const char* what);

 private:
  GlobalOptions options_;
  bool remote_ = false;
  std::map<std::string, SessionTokens> jar_;
  std::shared_ptr<hdeform::service::Server> server_;  // declared first: destroyed last
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<pb::Deformation::Stub> stub_;
};

// "sessions/abc" → "abc"; "abc" → "abc".
std::string session_id_of(const std::string& name);
std::string session_name_of(const std::string& id_or_name);
// 16 random lowercase hex characters (session ids, request ids).
std::string random_id();

// One session on the server, with its routing key (= its id; see docs/deployment.md).
class SessionClient {
 public:
  SessionClient(Connection& conn, std::string name);

  // MESH is an existing file (uploaded in 1 MiB chunks) or else a library mesh name.
  // `repair` (optional): CreateSessionHeader.repair for an uploaded file; what it changed
  // is printed on stderr.
  static SessionClient create(Connection& conn, const std::string& mesh,
                              const pb::MeshRepair* repair = nullptr);
  static SessionClient import(Connection& conn, const pb::Snapshot& snapshot);
  // Re-creates a session under a chosen id (e.g. its old one, after a replica was lost).
  static SessionClient import(Connection& conn, const pb::Snapshot& snapshot,
                              const std::string& session_id);

  const std::string& name() const { return name_; }
  const std::string& route_key() const { return key_; }
  const pb::Session& info() const { return info_; }
  // The session's tokens when this run created it, else nullptr.
  const SessionTokens* tokens() const { return conn_->tokens_for(session_id_of(name_)); }

  pb::Session get();
  pb::Session set_constraints(const pb::Constraints& constraints);
  pb::Session set_beta(double value, pb::BetaUnits units);
  pb::Session set_beta(const pb::Beta& beta);  // automatic β: picked at the current transforms
  // One Deform stream message: these transforms and β together (an automatic β is picked at
  // these transforms); returns the frame.
  pb::Frame deform(const std::vector<pb::HandleTransform>& transforms, std::int64_t sequence,
                   const pb::Beta& beta, bool energies = false);
  pb::Frame update(const std::vector<pb::HandleTransform>& transforms, std::int64_t sequence,
                   bool energies = false);
  pb::SweepResponse sweep(const std::vector<double>& betas, pb::BetaUnits units,
                          const std::vector<pb::HandleTransform>& transforms);
  // Downloads the current (or rest) mesh into `path`; returns the number of bytes. A mesh
  // with NaN/Inf vertex coordinates is not written (CliError).
  std::size_t download(const std::string& path, pb::MeshFormat format, bool rest = false,
                       const MeshOutputOptions& options = {});
  pb::Snapshot export_snapshot(bool include_mesh);
  pb::Timeline set_timeline(const pb::Timeline& timeline);
  // ExportAnimation into `path` (an animated GLB); returns the number of bytes.
  std::size_t export_animation(const std::string& path, const pb::ExportAnimationRequest& request);
  // ExportRig into `path`; returns the report (the first chunk's) and the file's size.
  pb::RigReport export_rig(const std::string& path, const pb::ExportRigRequest& request,
                           std::size_t* bytes);
  void remove();

 private:
  SessionClient(Connection& conn, std::string name, std::string key, pb::Session info);
  double timeout() const { return conn_->options().call_timeout_s; }
  // One call on this session with the retry policy; throws RpcError on failure. `doing`
  // describes the work for the terminal's status line (progress.h).
  void call(const char* rpc, const Connection::Attempt& attempt, double timeout_s,
            const std::string& doing = "");

  Connection* conn_;
  std::string name_;
  std::string key_;
  pb::Session info_;
};

// ListSessions, presenting every token known (--token and the jar): the sessions they open
// (all of them with the operator token).
std::vector<pb::Session> list_sessions(Connection& conn);

// Throws CliError "WHAT: the deformed mesh has N non-finite vertex coordinates …" when the
// frame's positions hold NaN/Inf.
void check_frame_finite(const pb::Frame& frame, const std::string& what);

// Files.
std::string read_file(const std::string& path);
void write_file(const std::string& path, const std::string& bytes);
// Output format from a file name's extension (.glb .obj .off .ply); throws CliError.
pb::MeshFormat mesh_format_for(const std::string& path);
std::string mesh_format_extension(pb::MeshFormat format);
pb::BetaUnits parse_beta_units(const std::string& text);

// Wall-clock milliseconds since `start`.
double ms_since(std::chrono::steady_clock::time_point start);

}  // namespace hdeform::cli
