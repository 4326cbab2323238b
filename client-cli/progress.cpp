#include "progress.h"

#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace hdeform::cli {

bool progress_enabled() {
  static const bool tty = ::isatty(STDERR_FILENO) == 1;
  return tty;
}

namespace {
constexpr auto kPeriod = std::chrono::milliseconds(200);

// Quick calls draw nothing: 500 ms, or HDEFORM_PROGRESS_DELAY_MS (0–60000; the test of the
// status line sets 0, since how fast a call is depends on the machine).
std::chrono::milliseconds delay() {
  static const std::chrono::milliseconds d = [] {
    const char* v = std::getenv("HDEFORM_PROGRESS_DELAY_MS");
    int ms = 500;
    if (v && *v) {
      int parsed = 0;
      const auto [end, ec] = std::from_chars(v, v + std::strlen(v), parsed);
      if (ec == std::errc() && *end == '\0' && parsed >= 0 && parsed <= 60000) ms = parsed;
    }
    return std::chrono::milliseconds(ms);
  }();
  return d;
}
}  // namespace

Activity::Activity(std::string what)
    : what_(std::move(what)), start_(std::chrono::steady_clock::now()) {
  if (progress_enabled()) thread_ = std::thread([this] { loop(); });
}

Activity::~Activity() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mu_);
    done_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void Activity::set(std::string what) {
  std::lock_guard lock(mu_);
  what_ = std::move(what);
}

void Activity::loop() {
  std::unique_lock lock(mu_);
  if (cv_.wait_for(lock, delay(), [this] { return done_; })) return;
  while (!done_) {
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    // \r + "erase to end of line": the status overwrites itself and leaves nothing behind.
    std::fprintf(stderr, "\r\033[Khdeform: %s \u2026 %.1f s", what_.c_str(), s);
    std::fflush(stderr);
    drawn_ = true;
    cv_.wait_for(lock, kPeriod, [this] { return done_; });
  }
  if (drawn_) {
    std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
  }
}

}  // namespace hdeform::cli
