#include "common/ready_file.h"

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>

#include <sys/prctl.h>
#include <unistd.h>

namespace hdeform {

namespace {

// Addresses are [host]:port or host:port from flags; escape what JSON needs anyway.
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

}  // namespace

void write_ready_file(const std::string& path, const std::string& grpc_address,
                      const std::string& http_address) {
  const std::filesystem::path target(path);
  // Appended, not "." + name: GCC 12's -Wrestrict misfires on operator+(const char*, string&&).
  std::string hidden = ".";
  hidden += target.filename().string();
  hidden += ".tmp" + std::to_string(getpid());
  const std::filesystem::path temporary = target.parent_path() / hidden;
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << "{\"grpc\": " << json_string(grpc_address) << ", \"http\": "
        << (http_address.empty() ? "null" : json_string(http_address)) << "}\n";
    out.flush();
    if (!out) throw std::runtime_error("--ready-file: cannot write " + temporary.string());
  }
  std::error_code ec;
  std::filesystem::rename(temporary, target, ec);
  if (ec) {
    std::filesystem::remove(temporary, ec);
    throw std::runtime_error("--ready-file: cannot create " + path + ": " + ec.message());
  }
}

void exit_with_parent(int parent_at_start) {
  if (prctl(PR_SET_PDEATHSIG, SIGTERM) != 0)
    throw std::system_error(errno, std::generic_category(), "--exit-with-parent: prctl");
  if (getppid() != parent_at_start) raise(SIGTERM);  // the parent died before prctl
}

}  // namespace hdeform
