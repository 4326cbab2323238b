// StateBackend on SQLite (sessions) plus one file per mesh, in a local folder.
#include "service/state/state_backend.h"
#include "service/state/state_keys.h"

#include "service/infra/cache.h"  // Sha256

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <set>
#include <string_view>
#include <unordered_set>
#include <utility>

namespace hdeform::service {
namespace {

namespace fs = std::filesystem;

constexpr std::int32_t kApplicationId = 0x6864666d;  // 'hdfm'
constexpr int kSchemaVersion = 2;  // 2: sessions.history
constexpr int kBusyTimeoutMs = 5000;
constexpr mode_t kFolderMode = 0700, kFileMode = 0600;  // the owner's alone

std::string errno_text(int err) { return std::strerror(err); }

// Closes a POSIX fd on scope exit.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = std::exchange(o.fd_, -1);
    }
    return *this;
  }
  int get() const { return fd_; }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_;
};

// A directory's entry changes (rename, unlink) are only durable once the directory is synced.
void fsync_dir(const fs::path& dir) {
  Fd fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (fd.get() < 0 || ::fsync(fd.get()) != 0)
    throw StateError("sqlite state: cannot sync folder " + dir.string() + ": " +
                     errno_text(errno));
}

void write_all(int fd, const std::string& bytes, const fs::path& path) {
  const char* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw StateError("cannot write " + path.string() + ": " + errno_text(errno));
    p += n;
    left -= static_cast<std::size_t>(n);
  }
}

// The whole file, or nullopt when it does not exist.
std::optional<std::string> read_file(const fs::path& path) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) {
    if (errno == ENOENT) return std::nullopt;
    throw StateError("cannot open " + path.string() + ": " + errno_text(errno));
  }
  std::string out;
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd.get(), buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw StateError("cannot read " + path.string() + ": " + errno_text(errno));
    if (n == 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

// Exclusive flock on DIR/lock: one server per folder. Released when the fd closes (also
// when the process dies, so a crash never leaves a stale lock behind).
Fd lock_folder(const fs::path& dir) {
  const fs::path path = dir / "lock";
  Fd fd(::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, kFileMode));
  if (fd.get() < 0 || ::fchmod(fd.get(), kFileMode) != 0)
    throw StateError("cannot open lock file " + path.string() + ": " + errno_text(errno));
  if (::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK)
      throw StateError("state folder " + dir.string() + " is in use by another hdeform-server");
    throw StateError("cannot lock " + path.string() + ": " + errno_text(errno));
  }
  return fd;
}

std::int64_t now_unix_ms() {
  using namespace std::chrono;
  return duration_cast<milliseconds>(system_clock::now().time_since_epoch()).count();
}

struct DbCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using Db = std::unique_ptr<sqlite3, DbCloser>;

struct StmtFinalizer {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Stmt = std::unique_ptr<sqlite3_stmt, StmtFinalizer>;

// Resets a prepared statement (and its bindings) when a call is done with it.
class StmtUse {
 public:
  explicit StmtUse(sqlite3_stmt* s) : s_(s) {}
  ~StmtUse() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }
  StmtUse(const StmtUse&) = delete;
  StmtUse& operator=(const StmtUse&) = delete;
  sqlite3_stmt* get() const { return s_; }

 private:
  sqlite3_stmt* s_;
};

// sqlite3_open_v2 of `name` (a path or a URI) with a StateError naming `path` on failure.
Db open_db(const std::string& name, int flags, const fs::path& path) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(name.c_str(), &raw, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  Db db(raw);
  if (rc != SQLITE_OK)
    throw StateError("sqlite " + path.string() + ": cannot open: " +
                     (raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc)));
  sqlite3_extended_result_codes(db.get(), 1);
  return db;
}

Db open_db(const fs::path& path, int flags) { return open_db(path.string(), flags, path); }

// Runs a single-integer query such as "PRAGMA application_id".
std::int64_t query_int(sqlite3* db, const char* sql, int* rc_out) {
  sqlite3_stmt* raw = nullptr;
  int rc = sqlite3_prepare_v2(db, sql, -1, &raw, nullptr);
  Stmt stmt(raw);
  std::int64_t value = 0;
  if (rc == SQLITE_OK) {
    rc = sqlite3_step(stmt.get());
    if (rc == SQLITE_ROW) {
      value = sqlite3_column_int64(stmt.get(), 0);
      rc = SQLITE_OK;
    } else if (rc == SQLITE_DONE) {
      rc = SQLITE_OK;
    }
  }
  *rc_out = rc;
  return value;
}

// Runs a single-text query such as "PRAGMA journal_mode=WAL"; "" when no row.
std::string query_text(sqlite3* db, const char* sql, int* rc_out) {
  sqlite3_stmt* raw = nullptr;
  int rc = sqlite3_prepare_v2(db, sql, -1, &raw, nullptr);
  Stmt stmt(raw);
  std::string value;
  if (rc == SQLITE_OK) rc = sqlite3_step(stmt.get());
  if (rc == SQLITE_ROW) {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt.get(), 0));
    if (text) value = text;
  }
  *rc_out = rc == SQLITE_ROW || rc == SQLITE_DONE ? SQLITE_OK : rc;
  return value;
}

// "file:" URI for sqlite3_open_v2 with SQLITE_OPEN_URI: '?', '#' and '%' in a path escaped.
std::string file_uri(const fs::path& path) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string uri = "file:";
  for (unsigned char c : path.string()) {
    if (std::isalnum(c) || c == '/' || c == '.' || c == '-' || c == '_' || c == '~') {
      uri += static_cast<char>(c);
    } else {
      uri += '%';
      uri += kHex[c >> 4];
      uri += kHex[c & 15];
    }
  }
  return uri;
}

// Decides, through a read-only connection (so nothing can be written, not even a journal
// rollback), whether an existing file is an hdeform state database this build can use.
// Returns true when it is blank (no application id, no tables) and still needs the schema.
bool check_existing_db(const fs::path& path) {
  // Without a -wal file the main file holds everything: read it immutable, which creates
  // no -wal/-shm side files (a plain read-only open of a WAL database would).
  std::error_code ec;
  const bool has_wal = fs::exists(path.string() + "-wal", ec);
  Db db = has_wal ? open_db(path, SQLITE_OPEN_READONLY)
                  : open_db(file_uri(path) + "?immutable=1", SQLITE_OPEN_READONLY | SQLITE_OPEN_URI,
                            path);
  sqlite3_busy_timeout(db.get(), kBusyTimeoutMs);
  int rc = SQLITE_OK;
  auto fail = [&](const std::string& what) {
    return StateError("sqlite " + path.string() + ": " + what + "; refusing to use it");
  };
  auto check = [&](const char* what) {
    if (rc == SQLITE_OK) return;
    if ((rc & 0xff) == SQLITE_NOTADB) throw fail("not a SQLite database (corrupt or foreign file)");
    throw fail(std::string("cannot read ") + what + ": " + sqlite3_errmsg(db.get()));
  };
  const std::int64_t tables = query_int(db.get(), "SELECT count(*) FROM sqlite_schema", &rc);
  check("schema");
  const std::int64_t app_id = query_int(db.get(), "PRAGMA application_id", &rc);
  check("application_id");
  const std::int64_t version = query_int(db.get(), "PRAGMA user_version", &rc);
  check("user_version");

  if (app_id == 0 && tables == 0 && version == 0) return true;  // blank SQLite file
  if (app_id != kApplicationId) {
    char hex[16];
    std::snprintf(hex, sizeof hex, "0x%08x", static_cast<std::uint32_t>(app_id));
    throw fail(std::string("belongs to another program (application_id ") + hex +
               ", hdeform is 0x6864666d)");
  }
  if (version > kSchemaVersion)
    throw fail("schema version " + std::to_string(version) + " is newer than this server's (" +
               std::to_string(kSchemaVersion) + "); upgrade hdeform-server");
  return version < kSchemaVersion;
}

void exec(sqlite3* db, const fs::path& path, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    throw StateError("sqlite " + path.string() + ": " + msg);
  }
}

// Removes the temp files a crash during a write can leave behind ("KEY.mesh.tmp.XXXXXX",
// "KEY.order.tmp.XXXXXX"), and makes the files the owner's alone (an older server wrote
// meshes 0644).
void tidy_files(const fs::path& folder) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".tmp.") != std::string::npos) fs::remove(entry.path(), ec);
    else if (entry.is_regular_file(ec)) ::chmod(entry.path().c_str(), kFileMode);
  }
}

// The state holds every session's token hashes and every uploaded mesh: the folder is the
// owner's alone (0700). One that another user owns, or may write to, is refused: they could
// replace the records or the meshes this server loads.
void make_private_folder(const fs::path& dir) {
  std::error_code ec;
  const bool created = fs::create_directories(dir, ec);
  if (ec) throw StateError("cannot create state folder " + dir.string() + ": " + ec.message());
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0)
    throw StateError("cannot stat state folder " + dir.string() + ": " + errno_text(errno));
  if (st.st_uid != ::geteuid())
    throw StateError("state folder " + dir.string() + " belongs to another user (uid " +
                     std::to_string(st.st_uid) + "); use a folder of your own");
  if (created || (st.st_mode & 077) != 0) {
    if ((st.st_mode & 022) != 0 && !created)
      throw StateError("state folder " + dir.string() + " is writable by other users (mode " +
                       fmt::format("{:04o}", st.st_mode & 07777) + "); run: chmod 700 " +
                       dir.string());
    if (::chmod(dir.c_str(), kFolderMode) != 0)
      throw StateError("cannot chmod 700 " + dir.string() + ": " + errno_text(errno));
  }
}

class SqliteState final : public StateBackend {
 public:
  explicit SqliteState(const fs::path& dir) : dir_(dir), db_path_(dir / "state.sqlite3"),
                                              meshes_(dir / "meshes"), derived_(dir / "derived") {
    make_private_folder(dir_);
    lock_ = lock_folder(dir_);
    open_database();
    make_private_folder(meshes_);
    make_private_folder(derived_);
    tidy_files(meshes_);  // safe: we hold the folder lock
    tidy_files(derived_);
    spdlog::info("state: {}", describe());
  }

  std::string describe() const override { return "sqlite " + db_path_.string(); }

  bool create_session(const std::string& id, const std::string& record,
                      const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    check_hashes(token_hashes);
    std::lock_guard lock(mu_);
    Transaction t(*this);
    {
      StmtUse s(insert_.get());
      bind_id_record(s.get(), id, record);
      step_done(s.get(), "create session");
    }
    if (sqlite3_changes(db_.get()) != 1) return false;
    index_locked(id, token_hashes);
    t.commit();
    return true;
  }

  void put_session(const std::string& id, const std::string& record,
                   const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    check_hashes(token_hashes);
    std::lock_guard lock(mu_);
    Transaction t(*this);
    {
      StmtUse s(upsert_.get());
      bind_id_record(s.get(), id, record);
      step_done(s.get(), "put session");
    }
    index_locked(id, token_hashes);
    t.commit();
  }

  std::vector<std::string> sessions_for(const std::vector<std::string>& token_hashes) override {
    check_hashes(token_hashes);
    std::lock_guard lock(mu_);
    std::set<std::string> ids;
    for (const auto& h : token_hashes) {
      StmtUse s(token_ids_.get());
      bind_blob(s.get(), 1, h);
      int rc;
      while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
        const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(s.get(), 0));
        ids.emplace(text ? text : "");
      }
      if (rc != SQLITE_DONE) throw error("sessions for a token");
    }
    return {ids.begin(), ids.end()};
  }

  void index_session(const std::string& id, const std::vector<std::string>& token_hashes) override {
    check_session_id(id);
    check_hashes(token_hashes);
    std::lock_guard lock(mu_);
    Transaction t(*this);
    index_locked(id, token_hashes);
    t.commit();
  }

  std::optional<std::string> get_session(const std::string& id) override {
    check_session_id(id);
    std::lock_guard lock(mu_);
    StmtUse s(select_.get());
    bind_text(s.get(), 1, id);
    const int rc = sqlite3_step(s.get());
    if (rc == SQLITE_DONE) return std::nullopt;
    if (rc != SQLITE_ROW) throw error("get session");
    return column_bytes(s.get());
  }

  bool put_history(const std::string& id, const std::string& history) override {
    check_session_id(id);
    std::lock_guard lock(mu_);
    StmtUse s(put_history_.get());
    bind_text(s.get(), 1, id);
    bind_blob(s.get(), 2, history);
    step_done(s.get(), "put history");
    return sqlite3_changes(db_.get()) == 1;
  }

  std::optional<std::string> get_history(const std::string& id) override {
    check_session_id(id);
    std::lock_guard lock(mu_);
    StmtUse s(get_history_.get());
    bind_text(s.get(), 1, id);
    const int rc = sqlite3_step(s.get());
    if (rc == SQLITE_DONE) return std::nullopt;
    if (rc != SQLITE_ROW) throw error("get history");
    if (sqlite3_column_type(s.get(), 0) == SQLITE_NULL) return std::nullopt;
    return column_bytes(s.get());
  }

  void delete_session(const std::string& id) override {
    check_session_id(id);
    std::lock_guard lock(mu_);
    StmtUse s(delete_.get());
    bind_text(s.get(), 1, id);
    step_done(s.get(), "delete session");
  }

  bool delete_session_if(const std::string& id, const std::string& record) override {
    check_session_id(id);
    std::lock_guard lock(mu_);
    StmtUse s(delete_if_.get());
    bind_text(s.get(), 1, id);
    if (sqlite3_bind_blob64(s.get(), 2, record.data(), record.size(), SQLITE_STATIC) != SQLITE_OK)
      throw error("bind");
    step_done(s.get(), "delete session");
    return sqlite3_changes(db_.get()) == 1;
  }

  std::vector<std::string> list_sessions() override {
    std::lock_guard lock(mu_);
    StmtUse s(list_.get());
    std::vector<std::string> ids;
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(s.get(), 0));
      ids.emplace_back(text ? text : "");
    }
    if (rc != SQLITE_DONE) throw error("list sessions");
    return ids;
  }

  std::string put_mesh(const std::string& bytes) override {
    const std::string key = Sha256().add(bytes).hex();
    const fs::path path = mesh_path(key);
    std::error_code ec;
    // Same key and size: already stored (a torn or truncated file gets rewritten).
    if (const auto size = fs::file_size(path, ec); !ec && size == bytes.size()) return key;
    write_atomically(path, bytes);
    return key;
  }

  bool has_mesh(const std::string& key) override {
    check_mesh_key(key);
    std::error_code ec;
    return fs::exists(mesh_path(key), ec);
  }

  std::optional<std::string> get_mesh(const std::string& key) override {
    check_mesh_key(key);
    const fs::path path = mesh_path(key);
    auto bytes = read_file(path);
    if (bytes && Sha256().add(*bytes).hex() != key)
      throw StateError("sqlite state: mesh file " + path.string() +
                       " is corrupt (its SHA-256 does not match its name)");
    return bytes;
  }

  std::size_t purge_meshes(const std::vector<std::string>& keep) override {
    return purge_files(meshes_, ".mesh", keep);
  }

  // DIR/derived/KEY.order, written like a mesh (a crash leaves the old file or the new one).
  void put_derived(const std::string& key, const std::string& bytes) override {
    check_mesh_key(key);
    write_atomically(derived_path(key), bytes);
  }

  std::optional<std::string> get_derived(const std::string& key) override {
    check_mesh_key(key);
    return read_file(derived_path(key));
  }

  std::size_t purge_derived(const std::vector<std::string>& keep) override {
    return purge_files(derived_, ".order", keep);
  }

 private:
  void open_database() {
    std::error_code ec;
    const bool exists = fs::exists(db_path_, ec);
    bool needs_schema = true;
    // Check before writing anything: a foreign or newer file must stay byte-for-byte intact.
    if (exists && fs::file_size(db_path_, ec) > 0) needs_schema = check_existing_db(db_path_);

    // SQLite creates the database 0644 and gives its -wal and -shm files the database's
    // mode: create it (or narrow an older one) 0600 first.
    {
      Fd fd(::open(db_path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, kFileMode));
      if (fd.get() < 0 || ::fchmod(fd.get(), kFileMode) != 0)
        throw error("cannot create it 0600: " + errno_text(errno));
    }
    for (const char* suffix : {"-wal", "-shm"}) ::chmod((db_path_.string() + suffix).c_str(), kFileMode);
    db_ = open_db(db_path_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    sqlite3_busy_timeout(db_.get(), kBusyTimeoutMs);
    // journal_mode answers with the mode it got (a read-only folder, say, keeps "delete").
    int rc = SQLITE_OK;
    if (query_text(db_.get(), "PRAGMA journal_mode=WAL", &rc) != "wal")
      throw error("cannot switch to WAL mode");
    exec(db_.get(), db_path_, "PRAGMA synchronous=FULL");
    if (needs_schema) {
      // A blank file gets the tables; a version 1 file gains the history column.
      exec(db_.get(), db_path_, "BEGIN IMMEDIATE");
      exec(db_.get(), db_path_,
           "CREATE TABLE IF NOT EXISTS sessions(id TEXT PRIMARY KEY, record BLOB NOT NULL,"
           " updated_unix_ms INTEGER, history BLOB)");
      // The token index: a deleted record takes its entries along (the trigger), so no
      // delete path can leave one behind.
      exec(db_.get(), db_path_,
           "CREATE TABLE IF NOT EXISTS tokens(hash BLOB NOT NULL, id TEXT NOT NULL,"
           " PRIMARY KEY(hash, id)) WITHOUT ROWID;"
           "CREATE INDEX IF NOT EXISTS tokens_by_id ON tokens(id);"
           "CREATE TRIGGER IF NOT EXISTS tokens_of_deleted AFTER DELETE ON sessions"
           " BEGIN DELETE FROM tokens WHERE id = OLD.id; END;");
      if (query_int(db_.get(), "SELECT count(*) FROM pragma_table_info('sessions') WHERE name = 'history'",
                    &rc) == 0 &&
          rc == SQLITE_OK)
        exec(db_.get(), db_path_, "ALTER TABLE sessions ADD COLUMN history BLOB");
      if (rc != SQLITE_OK) throw error("cannot read the sessions table");
      const std::string finish = "PRAGMA application_id=" + std::to_string(kApplicationId) +
                                 ";PRAGMA user_version=" + std::to_string(kSchemaVersion) +
                                 ";COMMIT;";
      exec(db_.get(), db_path_, finish.c_str());
    }
    insert_ = prepare(
        "INSERT INTO sessions(id, record, updated_unix_ms) VALUES(?1, ?2, ?3)"
        " ON CONFLICT(id) DO NOTHING");
    upsert_ = prepare(
        "INSERT INTO sessions(id, record, updated_unix_ms) VALUES(?1, ?2, ?3)"
        " ON CONFLICT(id) DO UPDATE SET record = excluded.record,"
        " updated_unix_ms = excluded.updated_unix_ms");
    select_ = prepare("SELECT record FROM sessions WHERE id = ?1");
    delete_ = prepare("DELETE FROM sessions WHERE id = ?1");
    delete_if_ = prepare("DELETE FROM sessions WHERE id = ?1 AND record = ?2");
    list_ = prepare("SELECT id FROM sessions");
    put_history_ = prepare("UPDATE sessions SET history = ?2 WHERE id = ?1");
    unindex_ = prepare("DELETE FROM tokens WHERE id = ?1");
    index_ = prepare("INSERT OR IGNORE INTO tokens(hash, id) SELECT ?2, id FROM sessions WHERE id = ?1");
    token_ids_ = prepare("SELECT id FROM tokens WHERE hash = ?1");
    get_history_ = prepare("SELECT history FROM sessions WHERE id = ?1");
  }

  Stmt prepare(const char* sql) {
    sqlite3_stmt* raw = nullptr;
    if (sqlite3_prepare_v3(db_.get(), sql, -1, SQLITE_PREPARE_PERSISTENT, &raw, nullptr) !=
        SQLITE_OK)
      throw error("cannot prepare statement");
    return Stmt(raw);
  }

  StateError error(const std::string& what) const {
    return StateError("sqlite " + db_path_.string() + ": " + what + ": " +
                      sqlite3_errmsg(db_.get()));
  }

  void bind_text(sqlite3_stmt* s, int index, const std::string& text) {
    if (sqlite3_bind_text(s, index, text.data(), static_cast<int>(text.size()),
                          SQLITE_STATIC) != SQLITE_OK)
      throw error("bind");
  }

  void bind_id_record(sqlite3_stmt* s, const std::string& id, const std::string& record) {
    bind_text(s, 1, id);
    // data() is never null, so an empty record binds as a zero-length blob, not NULL.
    if (sqlite3_bind_blob64(s, 2, record.data(), record.size(), SQLITE_STATIC) != SQLITE_OK ||
        sqlite3_bind_int64(s, 3, now_unix_ms()) != SQLITE_OK)
      throw error("bind");
  }

  // Column 0 of the current row as bytes (an empty blob is data() null: "").
  static std::string column_bytes(sqlite3_stmt* s) {
    const auto* data = static_cast<const char*>(sqlite3_column_blob(s, 0));
    const int size = sqlite3_column_bytes(s, 0);
    return data ? std::string(data, static_cast<std::size_t>(size)) : std::string();
  }

  void bind_blob(sqlite3_stmt* s, int index, const std::string& bytes) {
    if (sqlite3_bind_blob64(s, index, bytes.data(), bytes.size(), SQLITE_STATIC) != SQLITE_OK)
      throw error("bind");
  }

  // The record's entries replaced by `token_hashes` (a record must exist for any to land).
  void index_locked(const std::string& id, const std::vector<std::string>& token_hashes) {
    {
      StmtUse s(unindex_.get());
      bind_text(s.get(), 1, id);
      step_done(s.get(), "index tokens");
    }
    for (const auto& h : token_hashes) {
      StmtUse s(index_.get());
      bind_text(s.get(), 1, id);
      bind_blob(s.get(), 2, h);
      step_done(s.get(), "index tokens");
    }
  }

  void check_hashes(const std::vector<std::string>& token_hashes) const {
    for (const auto& h : token_hashes)
      if (h.size() != 32) throw StateError(describe() + ": a token hash must be 32 bytes");
  }

  // BEGIN IMMEDIATE … COMMIT, rolled back when left without commit() (an exception).
  class Transaction {
   public:
    explicit Transaction(SqliteState& db) : db_(db) {
      exec(db_.db_.get(), db_.db_path_, "BEGIN IMMEDIATE");
    }
    ~Transaction() {
      if (!done_) sqlite3_exec(db_.db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
      exec(db_.db_.get(), db_.db_path_, "COMMIT");
      done_ = true;
    }
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;

   private:
    SqliteState& db_;
    bool done_ = false;
  };

  void step_done(sqlite3_stmt* s, const char* what) {
    if (sqlite3_step(s) != SQLITE_DONE) throw error(what);
  }

  void check_session_id(const std::string& id) const {
    if (!is_session_id(id))
      throw StateError(describe() + ": invalid session id (expected [A-Za-z0-9_-]{1,64})");
  }

  void check_mesh_key(const std::string& key) const {
    if (!is_mesh_key(key))
      throw StateError(describe() + ": invalid mesh key (expected 64 lower-case hex digits)");
  }

  fs::path mesh_path(const std::string& key) const { return meshes_ / (key + ".mesh"); }
  fs::path derived_path(const std::string& key) const { return derived_ / (key + ".order"); }

  // Drops the files `folder`/KEY`extension` whose KEY is not in `keep`.
  std::size_t purge_files(const fs::path& folder, const char* extension,
                          const std::vector<std::string>& keep) {
    const std::unordered_set<std::string> kept(keep.begin(), keep.end());
    std::size_t dropped = 0;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      const fs::path& p = entry.path();
      if (p.extension() != extension) continue;
      const std::string key = p.stem().string();
      if (!is_mesh_key(key) || kept.count(key)) continue;
      std::error_code rm;
      if (fs::remove(p, rm)) ++dropped;
    }
    if (ec) throw StateError("cannot list " + folder.string() + ": " + ec.message());
    if (dropped > 0) fsync_dir(folder);
    return dropped;
  }

  // Temp file in the same folder, fsync, rename over the final name, fsync the folder: a
  // crash leaves either no file or the complete one.
  void write_atomically(const fs::path& path, const std::string& bytes) {
    std::string tmpl = path.string() + ".tmp.XXXXXX";
    Fd fd(::mkostemp(tmpl.data(), O_CLOEXEC));
    if (fd.get() < 0)
      throw StateError("cannot create a temp file in " + path.parent_path().string() + ": " +
                       errno_text(errno));
    try {
      write_all(fd.get(), bytes, tmpl);
      if (::fchmod(fd.get(), kFileMode) != 0 || ::fsync(fd.get()) != 0)
        throw StateError("cannot sync " + tmpl + ": " + errno_text(errno));
      fd.reset();
      if (::rename(tmpl.c_str(), path.c_str()) != 0)
        throw StateError("cannot rename " + tmpl + ": " + errno_text(errno));
    } catch (...) {
      ::unlink(tmpl.c_str());
      throw;
    }
    fsync_dir(path.parent_path());
  }

  fs::path dir_, db_path_, meshes_, derived_;
  Fd lock_;
  std::mutex mu_;  // one connection; SQLite opened NOMUTEX, so we serialize here
  Db db_;
  Stmt insert_, upsert_, select_, delete_, delete_if_, list_, put_history_, get_history_, unindex_,
      index_, token_ids_;
};

}  // namespace

std::unique_ptr<StateBackend> open_sqlite_state(const std::filesystem::path& dir) {
  return std::make_unique<SqliteState>(dir);
}

}  // namespace hdeform::service
