#include "engine/runtime/two_threads.h"

namespace hdeform {

Helper& Helper::instance() {
  // Never destroyed: at exit, threads that outlive static destruction (gRPC's, the worker
  // pool's in a process that calls exit()) may still run a kernel. The thread sleeps in
  // await_change and ends with the process.
  static Helper* const h = new Helper;
  return *h;
}

}  // namespace hdeform
