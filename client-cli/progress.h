// A live status line on stderr for work that can take seconds (uploads, factorizations, an
// automatic β, a sweep), shown only when stderr is a terminal: scripts that capture stderr
// get the same lines with or without it, and no carriage returns.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace hdeform::cli {

// True when stderr is a terminal (isatty); then Activity draws, else it does nothing.
bool progress_enabled();

// While alive, after a short delay (so quick calls print nothing), redraws
// "hdeform: WHAT … 2.4 s" in place on stderr every 200 ms; erases it when destroyed.
class Activity {
 public:
  explicit Activity(std::string what);
  ~Activity();
  Activity(const Activity&) = delete;
  Activity& operator=(const Activity&) = delete;

  // Replaces the text (e.g. "uploading bunny.off: 3.0 of 12.5 MiB").
  void set(std::string what);

 private:
  void loop();

  std::mutex mu_;
  std::condition_variable cv_;
  std::string what_;
  bool done_ = false;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  std::thread thread_;
};

}  // namespace hdeform::cli
