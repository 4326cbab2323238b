// Two independent parts of one call on two threads: the caller's and one started for the
// call (the second half of a nested dissection, a system's right-hand side blocks beside its
// order and factorization). Those threads come from one process-wide budget, so
// that requests at once cannot multiply them: when the budget is spent (or no thread can be
// made) the caller runs both parts itself, in turn, with the same result, only later.
#pragma once

#include "engine/runtime/serial_openmp.h"

#include <cstdint>
#include <exception>
#include <future>
#include <system_error>
#include <utility>

namespace hdeform {

// The budget of threads run_beside may have started at once, process-wide.
struct BesideThreads {
  int limit = 0;             // set_beside_thread_limit; default: the machine's cores
  int running = 0;           // started and not yet joined
  std::uint64_t started = 0;  // since the process started
  std::uint64_t refused = 0;  // calls that ran both parts on the caller: budget spent, or no thread
};

// limit ≥ 0 threads at once (0: every call runs on its caller alone). Calls already running
// keep their thread; a lower limit holds back new ones until enough have ended.
void set_beside_thread_limit(int limit);
BesideThreads beside_threads();

namespace detail {
bool take_beside_thread();  // one thread of the budget; false (counted as refused) when spent
void return_beside_thread(bool made);  // made = false: no thread could be made (refused too)
}  // namespace detail

// Runs side() on a thread of the budget while main() runs on the caller, each with its
// OpenMP loops kept to its own thread (two parts already fill two cores); without a thread,
// main() then side() on the caller, with OpenMP as the caller has it. Returns when both are
// done; rethrows main's exception (side() has ended by then), else side's. Not OpenMP
// sections: CHOLMOD's calls (METIS, analysis) must not be nested in a parallel region
// (nested, LLVM's libomp leaked 176 bytes per region: scripts/sanitize.sh).
template <class Main, class Side>
void run_beside(Main&& main, Side&& side) {
  std::future<void> beside;
  if (detail::take_beside_thread()) {
    try {
      beside = std::async(std::launch::async, [&side] {
        SerialOpenMP serial;
        side();
      });
    } catch (const std::system_error&) {  // no thread to be had: both parts here
      detail::return_beside_thread(/*made=*/false);
    } catch (...) {  // std::bad_alloc: the call fails, and its thread goes back
      detail::return_beside_thread(/*made=*/false);
      throw;
    }
  }
  if (!beside.valid()) {
    main();
    side();
    return;
  }
  struct Return {  // after the side's thread has ended, whichever way this scope is left
    std::future<void>& f;
    ~Return() {
      if (f.valid()) f.wait();
      detail::return_beside_thread(/*made=*/true);
    }
  } give_back{beside};
  {
    SerialOpenMP serial;
    main();  // an exception here waits for side() in give_back, then leaves
  }
  beside.get();
}

}  // namespace hdeform
