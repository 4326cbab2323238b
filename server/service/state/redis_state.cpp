// StateBackend on Redis (hiredis, one blocking connection): shared by replicas.
#include "service/state/state_backend.h"
#include "service/state/state_keys.h"

#include "service/infra/cache.h"  // Sha256

#include <hiredis/hiredis.h>
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/time.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <atomic>
#include <cstring>
#include <initializer_list>
#include <mutex>
#include <span>
#include <string_view>
#include <unordered_set>

namespace hdeform::service {
namespace {

constexpr int kTimeoutSeconds = 2;
constexpr std::string_view kSessionPrefix = "hdeform:session:";
constexpr std::string_view kSessionSet = "hdeform:sessions";
// Set once per Redis dataset: a reconnection that finds it missing found an emptied store.
constexpr std::string_view kMarker = "hdeform:marker";
constexpr std::string_view kMeshPrefix = "hdeform:mesh:";
constexpr std::string_view kDerivedPrefix = "hdeform:derived:";
constexpr std::string_view kHistoryPrefix = "hdeform:history:";
constexpr std::string_view kTokenPrefix = "hdeform:token:";  // the scripts spell it too
constexpr std::string_view kSessionTokensPrefix = "hdeform:session-tokens:";

// Each write of a record keeps the id set and the token index with it, in one script: they
// never disagree with the records. `reindex` replaces the entries of id ARGV[2] (or [1]) by
// the hex hashes ARGV[first..]; its keys are built here ("hdeform:token:" = kTokenPrefix).
#define HDEFORM_REINDEX                                                                   \
  "local function reindex(tokens_key, id, first) "                                        \
  "for _, h in ipairs(redis.call('SMEMBERS', tokens_key)) do "                             \
  "redis.call('SREM', 'hdeform:token:' .. h, id) end "                                     \
  "redis.call('DEL', tokens_key) "                                                         \
  "for i = first, #ARGV do redis.call('SADD', 'hdeform:token:' .. ARGV[i], id) "           \
  "redis.call('SADD', tokens_key, ARGV[i]) end end "
// KEYS: record, id set, the record's token set; ARGV: record, id, hashes….
constexpr std::string_view kCreateScript =
    HDEFORM_REINDEX
    "if redis.call('SET', KEYS[1], ARGV[1], 'NX') then "
    "redis.call('SADD', KEYS[2], ARGV[2]) reindex(KEYS[3], ARGV[2], 3) return 1 end return 0";
constexpr std::string_view kPutScript =
    HDEFORM_REINDEX
    "redis.call('SET', KEYS[1], ARGV[1]) redis.call('SADD', KEYS[2], ARGV[2]) "
    "reindex(KEYS[3], ARGV[2], 3) return 1";
// KEYS: record, id set, history, the record's token set; ARGV: id[, record].
constexpr std::string_view kDeleteScript =
    HDEFORM_REINDEX
    "reindex(KEYS[4], ARGV[1], #ARGV + 1) redis.call('DEL', KEYS[1], KEYS[3]) "
    "redis.call('SREM', KEYS[2], ARGV[1]) return 1";
constexpr std::string_view kDeleteIfScript =
    HDEFORM_REINDEX
    "if redis.call('GET', KEYS[1]) == ARGV[2] then reindex(KEYS[4], ARGV[1], #ARGV + 1) "
    "redis.call('DEL', KEYS[1], KEYS[3]) redis.call('SREM', KEYS[2], ARGV[1]) return 1 end "
    "return 0";
// KEYS: record, its token set; ARGV: id, hashes….
constexpr std::string_view kIndexScript =
    HDEFORM_REINDEX
    "if redis.call('EXISTS', KEYS[1]) == 1 then reindex(KEYS[2], ARGV[1], 2) end return 1";
#undef HDEFORM_REINDEX
// A history only beside a record: none is left behind by a write racing a delete.
constexpr std::string_view kPutHistoryScript =
    "if redis.call('EXISTS', KEYS[1]) == 1 then redis.call('SET', KEYS[2], ARGV[1]) "
    "return 1 end return 0";

struct RedisUrl {
  std::string host;
  int port = 6379;
  std::string user;      // Redis 6 ACL user; empty: the default user
  std::string password;  // empty: no AUTH
  int db = 0;
};

// The URL with everything up to the last '@' masked, so an error never shows a password.
std::string redact(const std::string& url) {
  const auto at = url.rfind('@');
  if (at == std::string::npos) return url;
  const auto scheme = url.find("://");
  const std::size_t start = scheme == std::string::npos ? 0 : scheme + 3;
  return url.substr(0, start) + "***" + url.substr(at);
}

bool parse_int(std::string_view text, int lo, int hi, int* out) {
  if (text.empty()) return false;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *out);
  return ec == std::errc() && end == text.data() + text.size() && *out >= lo && *out <= hi;
}

// %XX escapes, so a password may hold '@', '/' or ':'.
bool percent_decode(std::string_view in, std::string* out) {
  out->clear();
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (in[i] != '%') {
      *out += in[i];
      continue;
    }
    unsigned value = 0;
    if (i + 2 >= in.size()) return false;
    const auto [end, ec] = std::from_chars(in.data() + i + 1, in.data() + i + 3, value, 16);
    if (ec != std::errc() || end != in.data() + i + 3) return false;
    *out += static_cast<char>(value);
    i += 2;
  }
  return true;
}

// host:port[/db], for messages (never the password).
std::string where(const RedisUrl& url) {
  std::string out = url.host.find(':') != std::string::npos ? "[" + url.host + "]" : url.host;
  out += ":" + std::to_string(url.port);
  if (url.db != 0) out += "/" + std::to_string(url.db);
  return out;
}

// redis://[[USER]:PASSWORD@]HOST[:PORT][/DB]; HOST may be a bracketed IPv6 address.
RedisUrl parse_url(const std::string& url) {
  auto bad = [&](const std::string& why) {
    return StateError("invalid redis URL '" + redact(url) + "' (" + why +
                      "; expected redis://[:PASSWORD@]HOST[:PORT][/DB])");
  };
  constexpr std::string_view kScheme = "redis://";
  if (url.compare(0, kScheme.size(), kScheme) != 0) throw bad("it must start with redis://");
  std::string_view rest(url);
  rest.remove_prefix(kScheme.size());

  RedisUrl out;
  if (const auto at = rest.rfind('@'); at != std::string_view::npos) {
    const std::string_view userinfo = rest.substr(0, at);
    rest.remove_prefix(at + 1);
    const auto colon = userinfo.find(':');
    if (colon == std::string_view::npos) throw bad("user name without a password");
    if (!percent_decode(userinfo.substr(0, colon), &out.user) ||
        !percent_decode(userinfo.substr(colon + 1), &out.password))
      throw bad("bad %-escape in the credentials");
  }

  const auto slash = rest.find('/');
  std::string_view hostport = rest.substr(0, slash);
  if (slash != std::string_view::npos) {
    const std::string_view db = rest.substr(slash + 1);
    if (!db.empty() && !parse_int(db, 0, 1 << 20, &out.db))
      throw bad("the database must be a number");
  }

  std::string_view port;
  if (!hostport.empty() && hostport.front() == '[') {
    const auto close = hostport.find(']');
    if (close == std::string_view::npos) throw bad("unclosed '[' in the host");
    out.host = std::string(hostport.substr(1, close - 1));
    const std::string_view after = hostport.substr(close + 1);
    if (!after.empty() && after.front() != ':') throw bad("junk after the host");
    if (!after.empty()) port = after.substr(1);
    if (after == ":") throw bad("empty port");
  } else {
    const auto colon = hostport.find(':');
    out.host = std::string(hostport.substr(0, colon));
    if (colon != std::string_view::npos) {
      port = hostport.substr(colon + 1);
      if (port.empty()) throw bad("empty port");
    }
  }
  if (out.host.empty()) throw bad("no host");
  for (char c : out.host)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == ':' ||
          c == '_'))
      throw bad("bad character in the host");
  if (!port.empty() && !parse_int(port, 1, 65535, &out.port))
    throw bad("the port must be a number in 1..65535");
  return out;
}

// hiredis writes with write(2): on a socket the server has closed that raises SIGPIPE, which
// would kill the process. Block it on this thread for the call and swallow one it caused.
class SigpipeGuard {
 public:
  SigpipeGuard() {
    sigemptyset(&pipe_);
    sigaddset(&pipe_, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_, &old_);
    sigset_t pending;
    sigpending(&pending);
    pending_before_ = sigismember(&pending, SIGPIPE) == 1;
  }
  ~SigpipeGuard() {
    sigset_t pending;
    sigpending(&pending);
    if (!pending_before_ && sigismember(&pending, SIGPIPE) == 1) {
      const timespec zero{0, 0};
      sigtimedwait(&pipe_, nullptr, &zero);
    }
    pthread_sigmask(SIG_SETMASK, &old_, nullptr);
  }
  SigpipeGuard(const SigpipeGuard&) = delete;
  SigpipeGuard& operator=(const SigpipeGuard&) = delete;

 private:
  sigset_t pipe_, old_;
  bool pending_before_ = false;
};

struct ContextFree {
  void operator()(redisContext* c) const { redisFree(c); }
};
using Context = std::unique_ptr<redisContext, ContextFree>;

struct ReplyFree {
  void operator()(redisReply* r) const { freeReplyObject(r); }
};
using Reply = std::unique_ptr<redisReply, ReplyFree>;

std::string lower_first(std::string s) {
  if (!s.empty()) s[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(s[0])));
  return s;
}

// Sends one command on `c` (binary-safe arguments); nullptr when the connection failed.
Reply send(redisContext* c, std::span<const std::string_view> args) {
  std::vector<const char*> argv;
  std::vector<std::size_t> lens;
  argv.reserve(args.size());
  lens.reserve(args.size());
  for (std::string_view a : args) {
    argv.push_back(a.data());
    lens.push_back(a.size());
  }
  return Reply(static_cast<redisReply*>(
      redisCommandArgv(c, static_cast<int>(argv.size()), argv.data(), lens.data())));
}
Reply send(redisContext* c, std::initializer_list<std::string_view> args) {
  return send(c, std::span<const std::string_view>(args.begin(), args.size()));
}

// Redis could not be reached (yet), as opposed to refusing us: wait_for_redis_state tries
// again. why() is the cause alone, for the waiting message.
class Unreachable : public StateError {
 public:
  Unreachable(const std::string& message, std::string why)
      : StateError(message), why_(std::move(why)) {}
  const std::string& why() const { return why_; }

 private:
  std::string why_;
};

// `who` names the server in messages ("redis HOST:PORT").
void check_setup_reply(redisContext* c, const Reply& r, const std::string& who,
                       const char* what) {
  if (!r) {
    const std::string why = lower_first(c->errstr);
    throw Unreachable(who + ": " + what + ": " + why, why);
  }
  if (r->type == REDIS_REPLY_ERROR) {
    const std::string text(r->str, r->len);
    // A Redis that is starting answers LOADING until it has read its dataset.
    if (text.rfind("LOADING", 0) == 0)
      throw Unreachable(who + ": " + what + " failed: " + text, "still loading its dataset");
    throw StateError(who + ": " + what + " failed: " + text);
  }
}

// A fresh connection with AUTH, SELECT and PING done.
Context connect_to(const RedisUrl& url, const std::string& who) {
  const timeval timeout{kTimeoutSeconds, 0};
  Context c(redisConnectWithTimeout(url.host.c_str(), url.port, timeout));
  if (!c) throw StateError(who + ": cannot allocate a connection");
  if (c->err) {
    const std::string why = lower_first(c->errstr);
    throw Unreachable(who + ": cannot connect: " + why, why);
  }
  if (redisSetTimeout(c.get(), timeout) != REDIS_OK)
    throw StateError(who + ": cannot set the timeout: " + lower_first(c->errstr));
  if (!url.password.empty()) {
    // The reply text never contains the password, so it is safe to show.
    Reply r = url.user.empty() ? send(c.get(), {"AUTH", url.password})
                               : send(c.get(), {"AUTH", url.user, url.password});
    check_setup_reply(c.get(), r, who, "AUTH");
  }
  if (url.db != 0) {
    const std::string db = std::to_string(url.db);
    Reply r = send(c.get(), {"SELECT", db});
    check_setup_reply(c.get(), r, who, "SELECT");
  }
  // Proves at once that a Redis server (and one that accepts us) is at the other end.
  check_setup_reply(c.get(), send(c.get(), {"PING"}), who, "PING");
  return c;
}

class RedisState final : public StateBackend {
 public:
  explicit RedisState(const std::string& url) : url_(parse_url(url)), where_(where(url_)) {
    std::lock_guard lock(mu_);
    SigpipeGuard guard;
    connect_locked();
    spdlog::info("state: {}", describe());
  }

  std::string describe() const override { return "redis " + where_; }

  bool create_session(const std::string& id, const std::string& record,
                      const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    const std::string key = session_key(id), tokens = session_tokens_key(id);
    const auto hex = hex_hashes(token_hashes);
    std::vector<std::string_view> args = {"EVAL", kCreateScript, "3", key, kSessionSet, tokens,
                                          record, id};
    args.insert(args.end(), hex.begin(), hex.end());
    bool retried = false;
    Reply r = call("create session", args, &retried);
    if (integer(r, "create session") == 1) return true;
    // The first attempt may have been applied before the connection broke: then the stored
    // record is ours, and the id is ours too.
    return retried && get_session(id) == record;
  }

  void put_session(const std::string& id, const std::string& record,
                   const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    const std::string key = session_key(id), tokens = session_tokens_key(id);
    const auto hex = hex_hashes(token_hashes);
    std::vector<std::string_view> args = {"EVAL", kPutScript, "3", key, kSessionSet, tokens,
                                          record, id};
    args.insert(args.end(), hex.begin(), hex.end());
    integer(call("put session", args), "put session");
  }

  std::vector<std::string> sessions_for(const std::vector<std::string>& token_hashes) override {
    if (token_hashes.empty()) return {};
    std::vector<std::string> keys;
    for (const auto& h : hex_hashes(token_hashes)) keys.push_back(std::string(kTokenPrefix) + h);
    std::vector<std::string_view> args = {"SUNION"};
    args.insert(args.end(), keys.begin(), keys.end());
    Reply r = call("sessions for a token", args);
    if (r->type != REDIS_REPLY_ARRAY) throw unexpected("sessions for a token");
    std::vector<std::string> ids;
    for (std::size_t i = 0; i < r->elements; ++i) {
      const redisReply* e = r->element[i];
      if (e->type != REDIS_REPLY_STRING) throw unexpected("sessions for a token");
      ids.emplace_back(e->str, e->len);
    }
    return ids;
  }

  void index_session(const std::string& id, const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    const std::string key = session_key(id), tokens = session_tokens_key(id);
    const auto hex = hex_hashes(token_hashes);
    std::vector<std::string_view> args = {"EVAL", kIndexScript, "2", key, tokens, id};
    args.insert(args.end(), hex.begin(), hex.end());
    integer(call("index session", args), "index session");
  }

  std::optional<std::string> get_session(const std::string& id) override {
    check_session_id(id);
    return string_or_nil(call("get session", {"GET", session_key(id)}), "get session");
  }

  void delete_session(const std::string& id) override {
    check_session_id(id);
    Reply r = call("delete session", {"EVAL", kDeleteScript, "4", session_key(id), kSessionSet,
                                      history_key(id), session_tokens_key(id), id});
    integer(r, "delete session");
  }

  bool put_history(const std::string& id, const std::string& history) override {
    check_session_id(id);
    Reply r = call("put history",
                   {"EVAL", kPutHistoryScript, "2", session_key(id), history_key(id), history});
    return integer(r, "put history") == 1;
  }

  std::optional<std::string> get_history(const std::string& id) override {
    check_session_id(id);
    return string_or_nil(call("get history", {"GET", history_key(id)}), "get history");
  }

  bool delete_session_if(const std::string& id, const std::string& record) override {
    check_session_id(id);
    Reply r = call("delete session",
                   {"EVAL", kDeleteIfScript, "4", session_key(id), kSessionSet, history_key(id),
                    session_tokens_key(id), id, record});
    return integer(r, "delete session") == 1;
  }

  std::vector<std::string> list_sessions() override {
    Reply r = call("list sessions", {"SMEMBERS", kSessionSet});
    if (r->type != REDIS_REPLY_ARRAY) throw unexpected("list sessions");
    std::vector<std::string> ids;
    ids.reserve(r->elements);
    for (std::size_t i = 0; i < r->elements; ++i) {
      const redisReply* e = r->element[i];
      if (e->type != REDIS_REPLY_STRING) throw unexpected("list sessions");
      ids.emplace_back(e->str, e->len);
    }
    return ids;
  }

  std::string put_mesh(const std::string& bytes) override {
    const std::string key = Sha256().add(bytes).hex();
    // NX: a second put of the same bytes leaves the stored copy alone.
    call("put mesh", {"SET", mesh_key(key), bytes, "NX"});
    return key;
  }

  bool has_mesh(const std::string& key) override {
    check_mesh_key(key);
    return integer(call("has mesh", {"EXISTS", mesh_key(key)}), "has mesh") == 1;
  }

  std::uint64_t generation() const override { return generation_.load(); }

  std::optional<std::string> get_mesh(const std::string& key) override {
    check_mesh_key(key);
    auto bytes = string_or_nil(call("get mesh", {"GET", mesh_key(key)}), "get mesh");
    if (bytes && Sha256().add(*bytes).hex() != key)
      throw StateError(describe() + ": mesh " + key +
                       " is corrupt (its SHA-256 does not match its key)");
    return bytes;
  }

  std::size_t purge_meshes(const std::vector<std::string>& keep) override {
    return purge_keys(kMeshPrefix, keep, "purge meshes");
  }

  void put_derived(const std::string& key, const std::string& bytes) override {
    check_mesh_key(key);
    call("put derived", {"SET", std::string(kDerivedPrefix) + key, bytes});
  }

  std::optional<std::string> get_derived(const std::string& key) override {
    check_mesh_key(key);
    return string_or_nil(call("get derived", {"GET", std::string(kDerivedPrefix) + key}),
                         "get derived");
  }

  std::size_t purge_derived(const std::vector<std::string>& keep) override {
    return purge_keys(kDerivedPrefix, keep, "purge derived");
  }

 private:
  // Deletes the keys `prefix`KEY whose KEY is not in `keep`.
  std::size_t purge_keys(std::string_view prefix, const std::vector<std::string>& keep,
                         const char* what) {
    const std::unordered_set<std::string> kept(keep.begin(), keep.end());
    const std::string pattern = std::string(prefix) + "*";
    std::unordered_set<std::string> doomed;  // SCAN may return a key twice
    std::string cursor = "0";
    do {
      Reply r = call(what, {"SCAN", cursor, "MATCH", pattern, "COUNT", "1000"});
      if (r->type != REDIS_REPLY_ARRAY || r->elements != 2 ||
          r->element[0]->type != REDIS_REPLY_STRING || r->element[1]->type != REDIS_REPLY_ARRAY)
        throw unexpected(what);
      cursor.assign(r->element[0]->str, r->element[0]->len);
      const redisReply* keys = r->element[1];
      for (std::size_t i = 0; i < keys->elements; ++i) {
        std::string name(keys->element[i]->str, keys->element[i]->len);
        if (!kept.count(name.substr(prefix.size()))) doomed.insert(std::move(name));
      }
    } while (cursor != "0");

    std::size_t dropped = 0;
    for (const auto& name : doomed)
      dropped += static_cast<std::size_t>(integer(call(what, {"DEL", name}), what));
    return dropped;
  }

  static std::string session_key(const std::string& id) {
    return std::string(kSessionPrefix) + id;
  }
  static std::string mesh_key(const std::string& key) { return std::string(kMeshPrefix) + key; }
  static std::string history_key(const std::string& id) {
    return std::string(kHistoryPrefix) + id;
  }
  static std::string session_tokens_key(const std::string& id) {
    return std::string(kSessionTokensPrefix) + id;
  }
  // Hex in keys, so an operator can read them.
  std::vector<std::string> hex_hashes(const std::vector<std::string>& token_hashes) const {
    static constexpr char kHex[] = "0123456789abcdef";
    std::vector<std::string> out;
    for (const auto& h : token_hashes) {
      if (h.size() != 32) throw StateError(describe() + ": a token hash must be 32 bytes");
      std::string x;
      for (unsigned char c : h) {
        x += kHex[c >> 4];
        x += kHex[c & 15];
      }
      out.push_back(std::move(x));
    }
    return out;
  }

  void check_session_id(const std::string& id) const {
    if (!is_session_id(id))
      throw StateError(describe() + ": invalid session id (expected [A-Za-z0-9_-]{1,64})");
  }

  void check_mesh_key(const std::string& key) const {
    if (!is_mesh_key(key))
      throw StateError(describe() + ": invalid mesh key (expected 64 lower-case hex digits)");
  }

  StateError unexpected(const char* what) const {
    return StateError(describe() + ": " + what + ": unexpected reply");
  }

  long long integer(const Reply& r, const char* what) const {
    if (r->type != REDIS_REPLY_INTEGER) throw unexpected(what);
    return r->integer;
  }

  std::optional<std::string> string_or_nil(const Reply& r, const char* what) const {
    if (r->type == REDIS_REPLY_NIL) return std::nullopt;
    if (r->type != REDIS_REPLY_STRING) throw unexpected(what);
    return std::string(r->str, r->len);
  }

  // A fresh connection with AUTH and SELECT done; replaces ctx_ only when all succeeded.
  void connect_locked() {
    Context c = connect_to(url_, describe());
    Reply marked = send(c.get(), {"SET", kMarker, "1", "NX"});
    check_setup_reply(c.get(), marked, describe(), "SET marker");
    if (marked->type == REDIS_REPLY_STATUS && connected_before_) {
      ++generation_;
      spdlog::warn("state: {}: the store is empty again (restarted without persistence?)",
                   describe());
    }
    connected_before_ = true;
    ctx_ = std::move(c);
  }

  // Runs one command. A broken connection is dropped, reconnected once and the command
  // retried once (`retried` says so). A timeout is not retried: the server may have run it.
  Reply call(const char* what, std::initializer_list<std::string_view> args,
             bool* retried = nullptr) {
    return call(what, std::span<const std::string_view>(args.begin(), args.size()), retried);
  }
  Reply call(const char* what, std::span<const std::string_view> args, bool* retried = nullptr) {
    std::lock_guard lock(mu_);
    SigpipeGuard guard;
    for (int attempt = 0;; ++attempt) {
      if (!ctx_) connect_locked();
      Reply r = send(ctx_.get(), args);
      if (r) {
        if (r->type == REDIS_REPLY_ERROR)
          throw StateError(describe() + ": " + what + ": " + std::string(r->str, r->len));
        return r;
      }
      const std::string err = ctx_->errstr;
      const bool timed_out = ctx_->err == REDIS_ERR_IO && (err == std::strerror(EAGAIN) ||
                                                           err == std::strerror(EWOULDBLOCK));
      ctx_.reset();  // broken or out of step with its replies: never reused
      if (timed_out)
        throw StateError(describe() + ": " + what + ": no reply within " +
                         std::to_string(kTimeoutSeconds) + " s");
      if (attempt > 0) throw StateError(describe() + ": " + what + ": " + lower_first(err));
      spdlog::warn("state: {}: connection lost ({}); reconnecting", describe(), err);
      if (retried) *retried = true;
    }
  }

  RedisUrl url_;
  std::string where_;  // host:port[/db], for messages
  std::mutex mu_;      // guards ctx_: hiredis contexts are not thread-safe
  Context ctx_;        // null after a failure until the next call reconnects
  std::atomic<std::uint64_t> generation_{0};  // times the store was found emptied
  bool connected_before_ = false;             // guarded by mu_
};

}  // namespace

std::unique_ptr<StateBackend> open_redis_state(const std::string& url) {
  return std::make_unique<RedisState>(url);
}

bool wait_for_redis_state(const std::string& url_text, std::chrono::seconds wait,
                          const std::function<bool(std::chrono::milliseconds)>& pause) {
  using Clock = std::chrono::steady_clock;
  using std::chrono::milliseconds;
  const RedisUrl url = parse_url(url_text);  // an invalid URL fails at once
  const std::string who = "redis " + where(url);
  const auto start = Clock::now();
  const auto deadline = start + wait;
  auto next_log = start;
  for (;;) {
    try {
      SigpipeGuard guard;
      connect_to(url, who);
      return true;
    } catch (const Unreachable& e) {
      const auto now = Clock::now();
      if (now >= deadline) {
        const auto waited = std::chrono::duration_cast<std::chrono::seconds>(
            now - start + milliseconds(500));
        throw StateError(std::string(e.what()) + " (still not reachable after waiting " +
                         std::to_string(waited.count()) + " s: --state-redis-wait)");
      }
      if (now >= next_log) {
        const auto left = std::chrono::ceil<std::chrono::seconds>(deadline - now);
        spdlog::warn("state: {} not reachable yet ({}); retrying for up to {} s", who, e.why(),
                     left.count());
        next_log = now + std::chrono::seconds(2);
      }
      const auto rest = std::chrono::duration_cast<milliseconds>(deadline - now);
      if (!pause(std::min(milliseconds(500), rest + milliseconds(1)))) return false;
    }
  }
}

}  // namespace hdeform::service
