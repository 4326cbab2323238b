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

// Linux: SIGTERM to this process when the thread's parent exits (PR_SET_PDEATHSIG), and at
// once if it has already exited (reparented since `parent_at_start`). Call from the main
// thread before starting others: the death signal follows the thread that set it.
void exit_with_parent(int parent_at_start);

}  // namespace hdeform
