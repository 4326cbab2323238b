#include "two_threads.h"

namespace hdeform {

Helper& Helper::instance() {
  static Helper h;
  return h;
}

}  // namespace hdeform
