// Issue 35.6: the durable state (token hashes, every uploaded mesh) is the owner's alone —
// folder 0700, files 0600 — and a state folder other users may write to is refused at start.
#include "service_fixture.h"

#include <sys/stat.h>

#include <filesystem>
#include <fstream>

using namespace hdeform::testing;
namespace fs = std::filesystem;

namespace {

unsigned mode_of(const fs::path& p) {
  struct stat st {};
  EXPECT_EQ(::stat(p.c_str(), &st), 0) << p;
  return st.st_mode & 07777;
}

hdeform::service::ServerOptions in(const fs::path& dir) {
  hdeform::service::ServerOptions o;
  o.state_dir = dir.string();
  return o;
}

// Every file under `dir` (and the folders) is the owner's alone.
void expect_private(const fs::path& dir) {
  EXPECT_EQ(mode_of(dir), 0700u) << dir;
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_directory()) {
      EXPECT_EQ(mode_of(e.path()), 0700u) << e.path();
    } else {
      EXPECT_EQ(mode_of(e.path()), 0600u) << e.path();
      ++files;
    }
  }
  EXPECT_GE(files, 3u);  // at least the database, the lock and an uploaded mesh
}

}  // namespace

TEST(SecurityState, StateFilesAreReadableByTheirOwnerOnly) {
  const auto old_mask = ::umask(022);  // the usual default, under which 0644 files appear
  TempDir tmp;
  const fs::path dir = tmp.path / "new" / "state";
  {
    TestServer t(in(dir));
    pb::Session s;
    ASSERT_TRUE(t.upload(slurp(data_path("botsch-sorkine/bar.off")), "bar.off", &s).ok());
    t.server->shutdown();
  }
  expect_private(dir);
  EXPECT_TRUE(fs::exists(dir / "state.sqlite3"));
  EXPECT_FALSE(fs::is_empty(dir / "meshes"));

  // A folder an older server left 0755 with 0644 files is narrowed at start.
  fs::permissions(dir, fs::perms(0755));
  for (const auto& e : fs::recursive_directory_iterator(dir))
    fs::permissions(e.path(), e.is_directory() ? fs::perms(0755) : fs::perms(0644));
  {
    TestServer t(in(dir));
    t.server->shutdown();
  }
  expect_private(dir);
  ::umask(old_mask);
}

TEST(SecurityState, AStateFolderOthersMayWriteIsRefused) {
  TempDir tmp;
  const fs::path dir = tmp.path / "shared";
  fs::create_directories(dir);
  for (const unsigned mode : {0777u, 0770u, 0702u}) {
    fs::permissions(dir, fs::perms(mode));
    try {
      hdeform::service::Server server(in(dir));
      ADD_FAILURE() << "started on a state folder of mode " << std::oct << mode;
    } catch (const std::exception& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("writable by other users"), std::string::npos) << what;
      EXPECT_NE(what.find("chmod 700"), std::string::npos) << what;
    }
    EXPECT_FALSE(fs::exists(dir / "state.sqlite3")) << "nothing is written there";
  }
}
