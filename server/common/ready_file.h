// Telling a parent process the server is up: a readiness file with the bound addresses, and
// the server's exit when that parent dies (so a killed script leaves no orphan server).
#pragma once

#include <string>

namespace hdeform {

// Writes {"grpc": "<host:port>", "http": "<host:port>" or null} to `path` atomically (a
// temporary file in the same folder, then rename), so a reader never sees half of it.
// Throws std::runtime_error naming the path when it cannot.
void write_ready_file(const std::string& path, const std::string& grpc_address,
                      const std::string& http_address);

// Linux: SIGTERM to this process when its parent exits (PR_SET_PDEATHSIG), and at once if it
// has already exited (reparented since `parent_at_start`). Strictly it is the parent's
// *thread* that forked this process whose exit sends it: a parent starts the server from a
// thread that lives as long as it does (the Python client does, docs/python.md).
void exit_with_parent(int parent_at_start);

}  // namespace hdeform
