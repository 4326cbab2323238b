#pragma once
// Wall time in milliseconds on the steady clock, as the timings and logs report it.
#include <chrono>

namespace hdeform {

/** Milliseconds from t0 to t1 (default: now). */
inline double elapsed_ms(std::chrono::steady_clock::time_point t0,
                         std::chrono::steady_clock::time_point t1 = std::chrono::steady_clock::now()) {
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

}  // namespace hdeform
