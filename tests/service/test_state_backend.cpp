// Durable state backends (state_backend.h) against real stores: SQLite in a fresh temp
// folder and a redis-server started by the test on a free loopback port.
#include "service/state/state_backend.h"
#include "service_fixture.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <thread>

using hdeform::service::open_redis_state;
using hdeform::service::open_sqlite_state;
using hdeform::service::StateBackend;
using hdeform::service::StateError;
namespace fs = std::filesystem;
using hdeform::testing::TempDir;
using Clock = std::chrono::steady_clock;

namespace {

// ---- helpers: temp folders, files, sockets ----

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string all_bytes() {
  std::string s;
  for (int i = 0; i < 256; ++i) s += static_cast<char>(i);
  return s;
}

// A loopback port nobody listens on (bound then released; the race is harmless here).
int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

// One RESP command on a fresh connection; returns the first reply line ("" on failure).
// Enough for PING and SET, which the tests use to poke at the store behind the backend.
std::string resp(int port, const std::vector<std::string>& args) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<uint16_t>(port));
  std::string line;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) {
    std::string cmd = "*" + std::to_string(args.size()) + "\r\n";
    for (const auto& arg : args) cmd += "$" + std::to_string(arg.size()) + "\r\n" + arg + "\r\n";
    if (::send(fd, cmd.data(), cmd.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(cmd.size())) {
      char c;
      while (::recv(fd, &c, 1, 0) == 1 && c != '\n') line += c;
    }
  }
  ::close(fd);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

// ---- a real redis-server, owned by the test ----

class RedisServer {
 public:
  explicit RedisServer(std::vector<std::string> extra = {}) : port_(free_port()),
                                                              extra_(std::move(extra)) {
    start();
  }
  ~RedisServer() { stop(SIGTERM); }
  RedisServer(const RedisServer&) = delete;
  RedisServer& operator=(const RedisServer&) = delete;

  int port() const { return port_; }
  std::string url() const { return "redis://127.0.0.1:" + std::to_string(port_); }

  void start() {
    std::vector<std::string> args = {HDEFORM_REDIS_SERVER, "--port", std::to_string(port_),
                                     "--bind", "127.0.0.1", "--save", "", "--appendonly", "no",
                                     "--daemonize", "no"};
    args.insert(args.end(), extra_.begin(), extra_.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      // Dies with the test process, so a crashed test never leaves a server behind.
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
      const int null = ::open("/dev/null", O_WRONLY);
      ::dup2(null, 1);
      ::dup2(null, 2);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    wait_ready();
  }

  // SIGKILL: a crash (no goodbye on the clients' connections); SIGTERM: a clean stop.
  void stop(int sig) {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGCONT);  // a paused server would never handle SIGTERM
    ::kill(pid_, sig);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

  void pause() { ::kill(pid_, SIGSTOP); }
  void resume() { ::kill(pid_, SIGCONT); }

 private:
  void wait_ready() {
    const auto deadline = Clock::now() + std::chrono::seconds(10);
    while (Clock::now() < deadline) {
      const std::string reply = resp(port_, {"PING"});
      if (reply == "+PONG" || reply.rfind("-NOAUTH", 0) == 0) return;
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("redis-server exited at start (port taken?)");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    throw std::runtime_error("redis-server did not answer PING");
  }

  int port_;
  std::vector<std::string> extra_;
  pid_t pid_ = -1;
};

// ---- one harness per backend: open it, and corrupt a stored mesh behind its back ----

struct Harness {
  virtual ~Harness() = default;
  virtual std::unique_ptr<StateBackend> open() = 0;
  virtual void tamper_mesh(const std::string& key, const std::string& bytes) = 0;
};

struct SqliteHarness : Harness {
  TempDir dir;
  std::unique_ptr<StateBackend> open() override { return open_sqlite_state(dir.path / "state"); }
  void tamper_mesh(const std::string& key, const std::string& bytes) override {
    spit(dir.path / "state" / "meshes" / (key + ".mesh"), bytes);
  }
};

struct RedisHarness : Harness {
  RedisServer server;
  std::unique_ptr<StateBackend> open() override { return open_redis_state(server.url()); }
  void tamper_mesh(const std::string& key, const std::string& bytes) override {
    ASSERT_EQ(resp(server.port(), {"SET", "hdeform:mesh:" + key, bytes}), "+OK");
  }
};

class StateBackendTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "sqlite")
      harness_ = std::make_unique<SqliteHarness>();
    else
      harness_ = std::make_unique<RedisHarness>();
    state_ = harness_->open();
  }

  std::unique_ptr<Harness> harness_;
  std::unique_ptr<StateBackend> state_;
};

std::vector<std::string> sorted(std::vector<std::string> v) {
  std::sort(v.begin(), v.end());
  return v;
}

}  // namespace

TEST_P(StateBackendTest, DescribeNamesTheStore) {
  EXPECT_EQ(state_->describe().rfind(GetParam() + " ", 0), 0u) << state_->describe();
}

TEST_P(StateBackendTest, CreateSessionRefusesAnExistingId) {
  EXPECT_TRUE(state_->create_session("s-1", "first"));
  EXPECT_FALSE(state_->create_session("s-1", "second"));
  EXPECT_EQ(state_->get_session("s-1"), "first");
  EXPECT_EQ(state_->list_sessions(), std::vector<std::string>{"s-1"});
  state_->delete_session("s-1");
  EXPECT_TRUE(state_->create_session("s-1", "third"));  // free again once deleted
}

TEST_P(StateBackendTest, PutGetDeleteListRoundTrip) {
  EXPECT_EQ(state_->get_session("nobody"), std::nullopt);
  EXPECT_TRUE(state_->list_sessions().empty());
  state_->put_session("a", "record a");
  state_->put_session("B_2", "record b");
  EXPECT_EQ(state_->get_session("a"), "record a");
  EXPECT_EQ(sorted(state_->list_sessions()), (std::vector<std::string>{"B_2", "a"}));
  state_->put_session("a", "record a, v2");  // replaces
  EXPECT_EQ(state_->get_session("a"), "record a, v2");
  state_->delete_session("a");
  state_->delete_session("a");  // idempotent
  EXPECT_EQ(state_->get_session("a"), std::nullopt);
  EXPECT_EQ(state_->list_sessions(), std::vector<std::string>{"B_2"});
}

// A history lives beside its record: none without one, and it goes with the record.
TEST_P(StateBackendTest, AHistoryIsKeptOnlyBesideItsRecord) {
  EXPECT_FALSE(state_->put_history("h", "steps"));  // no record: nothing stored
  EXPECT_EQ(state_->get_history("h"), std::nullopt);
  ASSERT_TRUE(state_->create_session("h", "record"));
  EXPECT_EQ(state_->get_history("h"), std::nullopt);  // a record without a history yet
  const std::string binary = all_bytes();
  EXPECT_TRUE(state_->put_history("h", binary));
  EXPECT_EQ(state_->get_history("h"), binary);
  state_->put_session("h", "record v2");  // a new record keeps the history
  EXPECT_EQ(state_->get_history("h"), binary);
  EXPECT_TRUE(state_->put_history("h", "newer"));
  EXPECT_EQ(state_->get_history("h"), "newer");
  state_->delete_session("h");
  EXPECT_EQ(state_->get_history("h"), std::nullopt);
  ASSERT_TRUE(state_->create_session("h", "another session, same id"));
  EXPECT_EQ(state_->get_history("h"), std::nullopt);  // nothing of the deleted one
  EXPECT_TRUE(state_->put_history("h", "its own"));
  EXPECT_FALSE(state_->delete_session_if("h", "not this record"));
  EXPECT_EQ(state_->get_history("h"), "its own");
  EXPECT_TRUE(state_->delete_session_if("h", "another session, same id"));
  EXPECT_EQ(state_->get_history("h"), std::nullopt);
  EXPECT_THROW(state_->put_history("bad id!", "x"), StateError);
  EXPECT_THROW(state_->get_history("bad id!"), StateError);
}

// The token index: ListSessions finds a token's sessions without reading other records.
TEST_P(StateBackendTest, TheTokenIndexFollowsEveryWriteAndDelete) {
  const std::string a(32, 'a'), b(32, 'b'), c(32, '\0'), d(32, '\xff');
  EXPECT_TRUE(state_->sessions_for({a}).empty());
  ASSERT_TRUE(state_->create_session("one", "r1", {a, b}));
  state_->put_session("two", "r2", {c, b});
  EXPECT_EQ(sorted(state_->sessions_for({a})), std::vector<std::string>{"one"});
  EXPECT_EQ(sorted(state_->sessions_for({b})), (std::vector<std::string>{"one", "two"}));
  EXPECT_EQ(sorted(state_->sessions_for({a, c})), (std::vector<std::string>{"one", "two"}));
  EXPECT_TRUE(state_->sessions_for({d}).empty());
  EXPECT_TRUE(state_->sessions_for({}).empty());
  EXPECT_FALSE(state_->create_session("one", "r1 again", {d}));  // refused: index unchanged
  EXPECT_TRUE(state_->sessions_for({d}).empty());
  state_->put_session("one", "r1, rotated", {d, b});  // a put replaces the entries
  EXPECT_TRUE(state_->sessions_for({a}).empty());
  EXPECT_EQ(state_->sessions_for({d}), std::vector<std::string>{"one"});
  state_->delete_session("two");
  EXPECT_EQ(state_->sessions_for({b}), std::vector<std::string>{"one"});
  EXPECT_TRUE(state_->sessions_for({c}).empty());
  EXPECT_FALSE(state_->delete_session_if("one", "an older record"));
  EXPECT_EQ(state_->sessions_for({d}), std::vector<std::string>{"one"});
  EXPECT_TRUE(state_->delete_session_if("one", "r1, rotated"));
  EXPECT_TRUE(state_->sessions_for({d}).empty());
  EXPECT_TRUE(state_->sessions_for({b}).empty());
  // index_session: a record stored without entries gets them; no record, no entries.
  state_->put_session("old", "stored before the index");
  EXPECT_TRUE(state_->sessions_for({a}).empty());
  state_->index_session("old", {a});
  EXPECT_EQ(state_->sessions_for({a}), std::vector<std::string>{"old"});
  state_->index_session("nobody", {c});
  EXPECT_TRUE(state_->sessions_for({c}).empty());
  EXPECT_THROW(state_->sessions_for({"short"}), StateError);
  EXPECT_THROW(state_->put_session("x", "r", {"short"}), StateError);
}

TEST_P(StateBackendTest, BinaryRecordsKeepNulBytes) {
  const std::string binary = all_bytes() + std::string("\0\0tail\0", 7);
  state_->put_session("bin", binary);
  EXPECT_EQ(state_->get_session("bin"), binary);
  EXPECT_TRUE(state_->create_session("empty", ""));
  EXPECT_EQ(state_->get_session("empty"), std::string());  // present, not nullopt
  std::string big(3 << 20, '\0');
  std::mt19937 rng(7);
  for (auto& c : big) c = static_cast<char>(rng());
  state_->put_session("big", big);
  EXPECT_EQ(state_->get_session("big"), big);
}

TEST_P(StateBackendTest, PutMeshReturnsSha256AndIsIdempotent) {
  const std::string abc_key = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
  EXPECT_EQ(state_->get_mesh(abc_key), std::nullopt);
  EXPECT_EQ(state_->put_mesh("abc"), abc_key);
  EXPECT_EQ(state_->put_mesh("abc"), abc_key);
  EXPECT_EQ(state_->get_mesh(abc_key), "abc");

  const std::string binary = "OFF\n" + all_bytes() + std::string(1000, '\0');
  const std::string key = state_->put_mesh(binary);
  EXPECT_EQ(key.size(), 64u);
  EXPECT_EQ(state_->get_mesh(key), binary);
}

TEST_P(StateBackendTest, TamperedMeshThrows) {
  const std::string key = state_->put_mesh("the real mesh bytes");
  harness_->tamper_mesh(key, "the real mesh bytez");
  try {
    state_->get_mesh(key);
    FAIL() << "a mesh that does not match its key was returned";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt"), std::string::npos) << e.what();
  }
}

TEST_P(StateBackendTest, InvalidKeysAndIdsThrow) {
  const std::string upper = "BA7816BF8F01CFEA414140DE5DAE2223B00361A396177A9CB410FF61F20015AD";
  for (const std::string& key : {std::string("../../etc/passwd"), upper, std::string(63, 'a'),
                                std::string(65, 'a'), std::string(), std::string(64, 'g'),
                                std::string(62, 'a') + "/a"})
    EXPECT_THROW(state_->get_mesh(key), StateError) << key;
  for (const std::string& id : {std::string(), std::string("a/b"), std::string("../x"),
                               std::string("a b"), std::string(65, 'x'),
                               std::string("nul\0id", 6), std::string("é")}) {
    EXPECT_THROW(state_->put_session(id, "r"), StateError) << id;
    EXPECT_THROW(state_->create_session(id, "r"), StateError) << id;
    EXPECT_THROW(state_->get_session(id), StateError) << id;
    EXPECT_THROW(state_->delete_session(id), StateError) << id;
  }
  EXPECT_NO_THROW(state_->put_session(std::string(64, 'x'), "longest id"));
  EXPECT_TRUE(state_->list_sessions().size() == 1);
}

TEST_P(StateBackendTest, PurgeKeepsOnlyKept) {
  const std::string k1 = state_->put_mesh("mesh one");
  const std::string k2 = state_->put_mesh("mesh two");
  const std::string k3 = state_->put_mesh("mesh three");
  EXPECT_EQ(state_->purge_meshes({k1, std::string(64, 'f')}), 2u);
  EXPECT_EQ(state_->get_mesh(k1), "mesh one");
  EXPECT_EQ(state_->get_mesh(k2), std::nullopt);
  EXPECT_EQ(state_->get_mesh(k3), std::nullopt);
  EXPECT_EQ(state_->purge_meshes({k1}), 0u);
  EXPECT_EQ(state_->purge_meshes({}), 1u);
  EXPECT_EQ(state_->get_mesh(k1), std::nullopt);
}

// Derived data (the solver's orderings) by a mesh's hash: a put replaces, a purge keeps only
// what it is told, meshes and derived data are purged apart, and a bad key is refused.
TEST_P(StateBackendTest, DerivedDataIsKeptByMeshHashReplacedAndPurged) {
  const std::string a(64, 'a'), b(64, 'b');
  EXPECT_EQ(state_->get_derived(a), std::nullopt);
  state_->put_derived(a, std::string("first\0", 6));
  state_->put_derived(b, "other");
  EXPECT_EQ(state_->get_derived(a), std::string("first\0", 6));
  state_->put_derived(a, "second");
  EXPECT_EQ(state_->get_derived(a), "second");
  const std::string mesh = state_->put_mesh("a mesh");
  EXPECT_EQ(state_->purge_derived({a}), 1u);
  EXPECT_EQ(state_->get_derived(a), "second");
  EXPECT_EQ(state_->get_derived(b), std::nullopt);
  EXPECT_EQ(state_->get_mesh(mesh), "a mesh") << "purging derived data leaves the meshes";
  EXPECT_EQ(state_->purge_meshes({}), 1u);
  EXPECT_EQ(state_->get_derived(a), "second") << "purging meshes leaves derived data";
  EXPECT_THROW(state_->put_derived("../x", "y"), StateError);
  EXPECT_THROW(state_->get_derived(std::string(64, 'G')), StateError);
  state_.reset();
  state_ = harness_->open();
  EXPECT_EQ(state_->get_derived(a), "second");
}

TEST_P(StateBackendTest, PurgeScansManyMeshes) {
  // Redis: several SCAN pages (COUNT 1000). SQLite: fewer, each put costs two fsyncs.
  const int n = GetParam() == "redis" ? 2500 : 200;
  std::vector<std::string> keep;
  for (int i = 0; i < n; ++i) {
    const std::string key = state_->put_mesh("mesh #" + std::to_string(i));
    if (i % 10 == 0) keep.push_back(key);
  }
  EXPECT_EQ(state_->purge_meshes(keep), static_cast<std::size_t>(n - n / 10));
  for (const auto& key : keep) EXPECT_TRUE(state_->get_mesh(key).has_value());
}

TEST_P(StateBackendTest, PersistsAcrossReopen) {
  state_->put_session("kept", std::string("rec\0ord", 7));
  const std::string key = state_->put_mesh("persistent mesh");
  state_.reset();  // SQLite: closes and unlocks the folder; Redis: drops the connection
  state_ = harness_->open();
  EXPECT_EQ(state_->get_session("kept"), std::string("rec\0ord", 7));
  EXPECT_EQ(state_->list_sessions(), std::vector<std::string>{"kept"});
  EXPECT_EQ(state_->get_mesh(key), "persistent mesh");
  EXPECT_FALSE(state_->create_session("kept", "other"));
}

TEST_P(StateBackendTest, ConcurrentPutGet) {
  constexpr int kThreads = 4, kRounds = 150, kShared = 40;
  std::atomic<int> errors{0}, created{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      try {
        for (int i = 0; i < kRounds; ++i) {
          std::string id = std::to_string(t);  // (not "t" + ...: GCC 12's bogus -Wrestrict)
          id.insert(0, 1, 't').append("-").append(std::to_string(i % 20));
          const std::string record = id + ":" + std::to_string(i) + std::string("\0x", 2);
          state_->put_session(id, record);
          if (state_->get_session(id) != record) ++errors;
          const std::string mesh = "mesh " + std::to_string(i % 30);  // shared across threads
          const std::string key = state_->put_mesh(mesh);
          if (state_->get_mesh(key) != mesh) ++errors;
          if (i < kShared && state_->create_session("shared-" + std::to_string(i), id)) ++created;
          if (i % 25 == 0) state_->list_sessions();
        }
      } catch (const std::exception& e) {
        ADD_FAILURE() << "thread " << t << ": " << e.what();
        ++errors;
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(errors.load(), 0);
  EXPECT_EQ(created.load(), kShared);  // each shared id has exactly one owner
  EXPECT_EQ(state_->list_sessions().size(), static_cast<std::size_t>(kThreads * 20 + kShared));
}

INSTANTIATE_TEST_SUITE_P(StateBackend, StateBackendTest, ::testing::Values("sqlite", "redis"),
                         [](const auto& info) { return info.param; });

// ---------------------------------------------------------------- SQLite only

namespace {

// Writes a SQLite database the way another program would.
void make_sqlite_file(const fs::path& path, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
  EXPECT_EQ(rc, SQLITE_OK) << (err ? err : "");
  sqlite3_free(err);
  sqlite3_close(db);
}

std::int64_t pragma(const fs::path& path, const char* sql) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, sql, -1, &s, nullptr);
  std::int64_t v = -1;
  if (sqlite3_step(s) == SQLITE_ROW) v = sqlite3_column_int64(s, 0);
  sqlite3_finalize(s);
  sqlite3_close(db);
  return v;
}

std::string pragma_text(const fs::path& path, const char* sql) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, sql, -1, &s, nullptr);
  std::string v;
  if (sqlite3_step(s) == SQLITE_ROW) v = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  sqlite3_finalize(s);
  sqlite3_close(db);
  return v;
}

// Opening DIR must fail with a message naming the file and containing `why`, and leave
// the file byte-for-byte as it was (and no WAL/journal next to it).
void expect_refused_untouched(const fs::path& dir, const std::string& why) {
  const fs::path db = dir / "state.sqlite3";
  const std::string before = slurp(db);
  const auto mtime = fs::last_write_time(db);
  try {
    open_sqlite_state(dir);
    ADD_FAILURE() << "opened a file it must refuse";
  } catch (const StateError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(db.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(why), std::string::npos) << msg;
  }
  EXPECT_EQ(slurp(db), before);
  EXPECT_EQ(fs::last_write_time(db), mtime);
  EXPECT_FALSE(fs::exists(dir / "state.sqlite3-wal"));
  EXPECT_FALSE(fs::exists(dir / "state.sqlite3-journal"));
}

}  // namespace

TEST(SqliteState, CreatesTheDocumentedLayout) {
  TempDir tmp;
  const fs::path dir = tmp.path / "nested" / "state";
  auto state = open_sqlite_state(dir);
  EXPECT_EQ(state->describe(), "sqlite " + (dir / "state.sqlite3").string());
  const std::string key = state->put_mesh("layout");
  EXPECT_EQ(slurp(dir / "meshes" / (key + ".mesh")), "layout");
  const fs::path db = dir / "state.sqlite3";
  EXPECT_EQ(pragma(db, "PRAGMA application_id"), 0x6864666d);
  EXPECT_EQ(pragma(db, "PRAGMA user_version"), 2);
  EXPECT_EQ(pragma_text(db, "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(pragma(db, "SELECT count(*) FROM sqlite_schema WHERE name = 'sessions'"), 1);
  EXPECT_TRUE(fs::exists(dir / "lock"));
  // No temp file is left next to the mesh.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "meshes"), fs::directory_iterator{}), 1);
}

TEST(SqliteState, AnEmptyExistingFileGetsTheSchema) {
  TempDir tmp;
  spit(tmp.path / "state.sqlite3", "");
  open_sqlite_state(tmp.path)->put_session("x", "y");
  EXPECT_EQ(open_sqlite_state(tmp.path)->get_session("x"), "y");
}

TEST(SqliteState, ForeignSqliteFileIsRefusedAndUntouched) {
  TempDir tmp;
  make_sqlite_file(tmp.path / "state.sqlite3",
                   "PRAGMA application_id = 305419896;"  // 0x12345678
                   "CREATE TABLE accounts(name TEXT, balance INTEGER);"
                   "INSERT INTO accounts VALUES('alice', 100);");
  expect_refused_untouched(tmp.path, "another program (application_id 0x12345678");
}

TEST(SqliteState, PlainSqliteFileWithTablesIsRefused) {
  TempDir tmp;
  make_sqlite_file(tmp.path / "state.sqlite3", "CREATE TABLE sessions(id TEXT);");
  expect_refused_untouched(tmp.path, "another program (application_id 0x00000000");
}

TEST(SqliteState, NonDatabaseFileIsRefusedAndUntouched) {
  std::string junk(8192, '\0');
  std::mt19937 rng(42);
  for (auto& c : junk) c = static_cast<char>(rng());
  // Random bytes, and a file shorter than a SQLite header (must not pass for an empty one).
  for (const std::string& bytes : {junk, std::string("hello\n")}) {
    TempDir tmp;
    spit(tmp.path / "state.sqlite3", bytes);
    expect_refused_untouched(tmp.path, "not a SQLite database");
  }
}

TEST(SqliteState, NewerSchemaIsRefusedAndUntouched) {
  TempDir tmp;
  const fs::path dir = tmp.path / "odd ?#% name";  // the check opens it through a URI
  open_sqlite_state(dir)->put_session("s", "r");  // closed: WAL checkpointed
  make_sqlite_file(dir / "state.sqlite3", "PRAGMA user_version = 3;");
  ASSERT_FALSE(fs::exists(dir / "state.sqlite3-wal"));
  expect_refused_untouched(dir, "schema version 3 is newer");
}

// A state folder of a server from before histories were stored (schema 1) keeps its
// sessions and gains the history column.
TEST(SqliteState, SchemaOneIsUpgradedKeepingItsSessions) {
  TempDir tmp;
  fs::create_directories(tmp.path);
  fs::permissions(tmp.path, fs::perms::owner_all, fs::perm_options::replace);
  make_sqlite_file(tmp.path / "state.sqlite3",
                   "CREATE TABLE sessions(id TEXT PRIMARY KEY, record BLOB NOT NULL,"
                   " updated_unix_ms INTEGER);"
                   "INSERT INTO sessions VALUES('old', x'00726563', 1);"
                   "PRAGMA application_id = 1751410285; PRAGMA user_version = 1;");
  {
    auto state = open_sqlite_state(tmp.path);
    EXPECT_EQ(state->get_session("old"), std::string("\0rec", 4));
    EXPECT_EQ(state->get_history("old"), std::nullopt);
    EXPECT_TRUE(state->put_history("old", "steps"));
  }
  EXPECT_EQ(pragma(tmp.path / "state.sqlite3", "PRAGMA user_version"), 2);
  auto state = open_sqlite_state(tmp.path);  // a second open needs no upgrade
  EXPECT_EQ(state->get_history("old"), "steps");
}

TEST(SqliteState, SecondOpenOfALiveFolderThrows) {
  TempDir tmp;
  auto first = open_sqlite_state(tmp.path);
  first->put_session("owner", "first");
  try {
    open_sqlite_state(tmp.path);
    FAIL() << "two backends on one folder";
  } catch (const StateError& e) {
    EXPECT_EQ(std::string(e.what()),
              "state folder " + tmp.path.string() + " is in use by another hdeform-server");
  }
  EXPECT_EQ(first->get_session("owner"), "first");  // the first one is unharmed
  first.reset();
  EXPECT_EQ(open_sqlite_state(tmp.path)->get_session("owner"), "first");
}

TEST(SqliteState, TruncatedMeshIsRewrittenByTheNextPut) {
  TempDir tmp;
  auto state = open_sqlite_state(tmp.path);
  const std::string key = state->put_mesh("complete mesh");
  spit(tmp.path / "meshes" / (key + ".mesh"), "compl");
  EXPECT_THROW(state->get_mesh(key), StateError);
  EXPECT_EQ(state->put_mesh("complete mesh"), key);
  EXPECT_EQ(state->get_mesh(key), "complete mesh");
}

// ---------------------------------------------------------------- Redis only

TEST(RedisState, UnreachableServerThrowsQuicklyNamingHostPort) {
  const int port = free_port();
  const auto t0 = Clock::now();
  try {
    open_redis_state("redis://127.0.0.1:" + std::to_string(port));
    FAIL() << "connected to nobody";
  } catch (const StateError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("redis 127.0.0.1:" + std::to_string(port)), std::string::npos) << msg;
    EXPECT_NE(msg.find("connection refused"), std::string::npos) << msg;
  }
  EXPECT_LT(Clock::now() - t0, std::chrono::seconds(3));
}

TEST(RedisState, MalformedUrlsThrowWithoutThePassword) {
  for (const char* url :
       {"", "http://127.0.0.1:6379", "redis://", "redis://:6379", "redis://host:notaport",
        "redis://host:0", "redis://host:65536", "redis://host:", "redis://host/db1",
        "redis://host/-1", "redis://[::1", "redis://:hunter2@host:99999",
        "redis://:hunter2@host/x", "redis://hunter2@host", "redis://:bad%zzescape@host",
        "redis://ho st", "redis://host?timeout=1"}) {
    try {
      open_redis_state(url);
      ADD_FAILURE() << "accepted " << url;
    } catch (const StateError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("invalid redis URL"), std::string::npos) << msg;
      EXPECT_EQ(msg.find("hunter2"), std::string::npos) << msg;
    }
  }
}

TEST(RedisState, PasswordAndDatabase) {
  RedisServer server({"--requirepass", "s3cret/@:"});
  const std::string base = "127.0.0.1:" + std::to_string(server.port());
  auto state = open_redis_state("redis://:s3cret%2F%40%3A@" + base + "/3");
  EXPECT_EQ(state->describe(), "redis " + base + "/3");
  state->put_session("p", "in db 3");
  EXPECT_EQ(state->get_session("p"), "in db 3");
  EXPECT_TRUE(open_redis_state("redis://:s3cret%2F%40%3A@" + base + "/4")->list_sessions().empty());
  EXPECT_EQ(open_redis_state("redis://default:s3cret%2F%40%3A@" + base + "/3")->get_session("p"),
            "in db 3");
  try {
    open_redis_state("redis://:wrong-pw@" + base);
    FAIL() << "a wrong password was accepted";
  } catch (const StateError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(base), std::string::npos) << msg;
    EXPECT_NE(msg.find("AUTH"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("wrong-pw"), std::string::npos) << msg;
  }
  try {
    open_redis_state("redis://" + base);  // no password: refused at connect (PING)
    FAIL() << "no password was accepted";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("NOAUTH"), std::string::npos) << e.what();
  }
}

TEST(RedisState, SurvivesAServerRestart) {
  RedisServer server;
  auto state = open_redis_state(server.url());
  state->put_session("before", "restart");
  server.stop(SIGKILL);
  server.start();  // same port; --save '' so the data is gone, the backend must reconnect
  state->put_session("after", "restart");
  EXPECT_EQ(state->get_session("after"), "restart");
  EXPECT_EQ(state->get_session("before"), std::nullopt);

  // A big write into the dead connection gets EPIPE: SIGPIPE must not kill the process.
  server.stop(SIGKILL);
  server.start();
  const std::string big(4 << 20, 'b');
  state->put_session("big", big);
  EXPECT_EQ(state->get_session("big"), big);
}

TEST(RedisState, ServerDownThrowsNamingHostPortThenRecovers) {
  RedisServer server;
  auto state = open_redis_state(server.url());
  state->put_session("x", "1");
  server.stop(SIGTERM);
  const auto t0 = Clock::now();
  try {
    state->get_session("x");
    FAIL() << "a dead server answered";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(server.port())),
              std::string::npos)
        << e.what();
  }
  EXPECT_LT(Clock::now() - t0, std::chrono::seconds(3));
  server.start();
  EXPECT_EQ(state->get_session("x"), std::nullopt);  // reconnected (the data was not saved)
}

TEST(RedisState, HungServerTimesOutAfterTwoSeconds) {
  RedisServer server;
  auto state = open_redis_state(server.url());
  state->put_session("x", "1");
  server.pause();
  const auto t0 = Clock::now();
  EXPECT_THROW(state->get_session("x"), StateError);
  const auto took = Clock::now() - t0;
  EXPECT_GE(took, std::chrono::milliseconds(1500));
  EXPECT_LT(took, std::chrono::seconds(4));
  server.resume();
  EXPECT_EQ(state->get_session("x"), "1");  // a fresh connection, in step again
}

// A change the store does not acknowledge is refused UNAVAILABLE and not applied (nothing
// recorded, nobody told), so the client's retry with its request_id applies it once when
// the store is back.
TEST(RedisState, AChangeTheStoreRefusesIsNotAppliedAndItsRetryAppliesItOnce) {
  RedisServer redis;
  hdeform::service::ServerOptions o;
  o.state_redis = redis.url();
  hdeform::testing::TestServer t(o);
  namespace pb = hdeform::v1;
  pb::Session s = t.library_session("cactus");
  const auto created = s.version();
  redis.stop(SIGTERM);
  pb::SetBetaRequest r;
  r.set_name(s.name());
  r.mutable_beta()->set_value(0.3);
  r.set_client_id("alice");
  r.set_request_id("b-1");
  pb::Session out;
  grpc::ClientContext c1;
  auto st = t.stub->SetBeta(&c1, r, &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE) << st.error_message();
  EXPECT_NE(st.error_message().find("not applied"), std::string::npos) << st.error_message();
  redis.start();
  pb::ListHistoryRequest h;
  h.set_name(s.name());
  pb::ListHistoryResponse steps;
  {
    grpc::ClientContext c;
    pb::GetSessionRequest g;
    g.set_name(s.name());
    ASSERT_TRUE(t.stub->GetSession(&c, g, &out).ok());
    EXPECT_GE(out.version(), created);  // the refused change's number is skipped
    EXPECT_DOUBLE_EQ(out.beta().value(), 0.0);  // not applied
    grpc::ClientContext c5;
    ASSERT_TRUE(t.stub->ListHistory(&c5, h, &steps).ok());
    EXPECT_EQ(steps.total(), 0);  // nothing recorded
  }
  grpc::ClientContext c3;
  st = t.stub->SetBeta(&c3, r, &out);  // the client's retry
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.3);
  grpc::ClientContext c4;
  st = t.stub->SetBeta(&c4, r, &out);  // and a second one: answered, not applied again
  ASSERT_TRUE(st.ok()) << st.error_message();
  grpc::ClientContext c6;
  ASSERT_TRUE(t.stub->ListHistory(&c6, h, &steps).ok());
  EXPECT_EQ(steps.total(), 1);  // one β step
  hdeform::testing::TestServer b(o);  // stored: another replica restores it
  ASSERT_TRUE(b.get_session(s.name(), &out).ok());
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.3);
}

// A token rotation the store does not acknowledge is applied (the old tokens stop at once)
// and answered DATA_LOSS, never UNAVAILABLE, which clients retry.
TEST(RedisState, ATokenRotationAppliedButNotStoredIsDataLoss) {
  RedisServer redis;
  hdeform::service::ServerOptions o;
  o.state_redis = redis.url();
  hdeform::testing::TestServer t(o);
  namespace pb = hdeform::v1;
  const pb::Session s = t.library_session("cactus");
  redis.stop(SIGTERM);
  pb::RotateTokensRequest r;
  r.set_name(s.name());
  pb::Session out;
  grpc::ClientContext c;
  const auto st = t.stub->RotateTokens(&c, r, &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::DATA_LOSS) << st.error_message();
  EXPECT_NE(st.error_message().find("do not send it again"), std::string::npos)
      << st.error_message();
}

// Every answered move is in Redis: a move Redis does not acknowledge (stalled past the 2 s
// timeout, or down) is refused UNAVAILABLE and changes nothing — on UpdateHandles and on a
// Deform stream — even when the timed-out write lands after all (a stalled Redis resumes
// and runs it); the next answered move is what another replica restores.
TEST(RedisState, AMoveRedisDoesNotAcknowledgeIsRefusedAndNotApplied) {
  namespace pb = hdeform::v1;
  using hdeform::testing::translation;
  RedisServer redis;
  hdeform::service::ServerOptions o;
  o.state_redis = redis.url();
  hdeform::testing::TestServer a(o);
  const pb::Session s = hdeform::testing::constrained_cactus(a);
  pb::Frame f;
  ASSERT_TRUE(a.update(s.name(), 1, {translation(0.1, 0, 0)}, &f).ok());
  const auto answered = f.version();

  redis.pause();
  auto st = a.update(s.name(), 2, {translation(0.3, 0, 0)}, &f);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE) << st.error_message();
  EXPECT_NE(st.error_message().find("not applied"), std::string::npos) << st.error_message();
  redis.resume();  // and runs the write that timed out
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the flusher's turn
  pb::Session now;
  ASSERT_TRUE(a.get_session(s.name(), &now).ok());
  EXPECT_DOUBLE_EQ(now.transforms(0).translation().x(), 0.1);
  const auto refused = now.version();  // a refused move's version is not used again
  EXPECT_GT(refused, answered);
  {
    hdeform::testing::TestServer c(o);  // what another replica finds: the answered pose
    pb::Session there;
    ASSERT_TRUE(c.get_session(s.name(), &there).ok());
    EXPECT_DOUBLE_EQ(there.transforms(0).translation().x(), 0.1);
  }

  redis.stop(SIGTERM);
  {
    grpc::ClientContext ctx;
    auto stream = a.stub->Deform(&ctx);
    ASSERT_TRUE(stream->Write(hdeform::testing::deform_request(s.name(), 3, translation(0.4, 0, 0))));
    pb::Frame g;
    EXPECT_FALSE(stream->Read(&g));
    stream->WritesDone();
    const auto dst = stream->Finish();
    EXPECT_EQ(dst.error_code(), grpc::StatusCode::UNAVAILABLE) << dst.error_message();
  }
  redis.start();  // empty (no persistence): the next answered move writes the record again
  ASSERT_TRUE(a.get_session(s.name(), &now).ok());
  EXPECT_DOUBLE_EQ(now.transforms(0).translation().x(), 0.1);

  st = a.update(s.name(), 4, {translation(0.2, 0, 0)}, &f);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_GT(f.version(), refused);
  hdeform::testing::TestServer b(o);  // another replica finds exactly the last answered move
  ASSERT_TRUE(b.get_session(s.name(), &now).ok());
  EXPECT_EQ(now.version(), f.version());
  EXPECT_DOUBLE_EQ(now.transforms(0).translation().x(), 0.2);
}

// Idle on one replica is not idle everywhere: when replica A's copy expires after replica B
// wrote a newer record, A keeps its hands off it — B (and any other replica) goes on.
TEST(RedisState, AnExpiringReplicaNeverDeletesARecordAnotherOvertook) {
  namespace pb = hdeform::v1;
  RedisServer redis;
  hdeform::service::ServerOptions oa;
  oa.state_redis = redis.url();
  oa.session_ttl = std::chrono::seconds(1);
  hdeform::testing::TestServer a(oa);
  hdeform::service::ServerOptions ob;
  ob.state_redis = redis.url();
  hdeform::testing::TestServer b(ob);
  const pb::Session s = a.library_session("cactus");
  pb::Session out;
  ASSERT_TRUE(b.set_beta(s.name(), 0.3, &out).ok());  // B restores it and writes version 2
  std::this_thread::sleep_for(std::chrono::milliseconds(1800));  // A's copy expires (TTL 1 s)
  hdeform::testing::TestServer c(ob);  // a third replica finds B's record
  grpc::ClientContext ctx;
  pb::GetSessionRequest g;
  g.set_name(s.name());
  const auto st = c.stub->GetSession(&ctx, g, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.3);
}

// Redis restarted empty: the replica serving an uploaded session writes its record again on
// the next change — and its mesh, without which no other replica could restore it.
TEST(RedisState, AfterRedisRestartsEmptyTheNextChangeRewritesRecordAndMesh) {
  namespace pb = hdeform::v1;
  RedisServer redis;
  hdeform::service::ServerOptions o;
  o.state_redis = redis.url();
  hdeform::testing::TestServer a(o);
  pb::Session s;
  ASSERT_TRUE(a.upload(hdeform::testing::grid_off(12), "grid.off", &s).ok());
  pb::Session out;
  ASSERT_TRUE(a.set_beta(s.name(), 0.1, &out).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // the flusher wrote its history
  redis.stop(SIGKILL);
  redis.start();  // no persistence: empty
  auto st = a.set_beta(s.name(), 0.2, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  // Histories are written at most once a second (SessionStore::kHistoryPeriod).
  std::this_thread::sleep_for(std::chrono::milliseconds(1300));
  hdeform::testing::TestServer b(o);  // another replica restores it from Redis alone
  grpc::ClientContext ctx;
  pb::GetSessionRequest g;
  g.set_name(s.name());
  st = b.stub->GetSession(&ctx, g, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.2);
  EXPECT_EQ(out.vertex_count(), 144);
  // The whole history too, the step from before Redis lost everything included.
  grpc::ClientContext hctx;
  pb::ListHistoryRequest h;
  h.set_name(s.name());
  pb::ListHistoryResponse steps;
  st = b.stub->ListHistory(&hctx, h, &steps);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(steps.total(), 2);
  EXPECT_EQ(steps.steps(1).kind(), pb::STEP_KIND_BETA);
  EXPECT_EQ(steps.steps(0).kind(), pb::STEP_KIND_BETA);
}
