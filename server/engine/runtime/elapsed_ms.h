#pragma once
// Wall time on the steady clock: milliseconds as the timings and logs report them, and
// nanosecond timestamps for deadlines kept in atomics.
#include <chrono>
#include <cstdint>

namespace hdeform {

/** Milliseconds from t0 to t1 (default: now). */
inline double elapsed_ms(std::chrono::steady_clock::time_point t0,
                         std::chrono::steady_clock::time_point t1 = std::chrono::steady_clock::now()) {
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

/** Nanoseconds on the steady clock since its epoch: a timestamp an atomic can hold. */
inline std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace hdeform
