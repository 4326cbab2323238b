// The CLI's user-facing errors. No gRPC here: the job-file parser (hdeform_cli_job) and its
// fuzz target use them without the service.
#pragma once

#include <stdexcept>
#include <string>

namespace hdeform::cli {

// A user-facing error: main() prints what() as the single line on stderr and exits 1.
struct CliError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A parse error in an input file: main() prints it bare, "FILE:LINE: problem".
struct FileError : CliError {
  using CliError::CliError;
};

// "FILE:LINE: problem" (LINE 0: "FILE: problem").
inline FileError parse_error(const std::string& file, int line, const std::string& problem) {
  if (line > 0) return FileError(file + ":" + std::to_string(line) + ": " + problem);
  return FileError(file + ": " + problem);
}

}  // namespace hdeform::cli
