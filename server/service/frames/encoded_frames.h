// One encoding of a frame per encoding for all of a session's watchers: N watchers that ask
// for MESHOPT cost one encode of each frame (≈ 7 ms at 100K vertices, docs/benchmarks.md
// "Frame encodings"), not N. Holds only the newest frame's encodings.
#pragma once

#include "hdeform/v1/deform.pb.h"

#include <map>
#include <memory>
#include <mutex>

namespace hdeform::service {

class EncodedFrameCache {
 public:
  // `event` (a frame event as broadcast, FLOAT32) for a watcher that asked for `format`: the
  // event itself when it goes out as it is, else its encoding, made once per encoding for
  // as long as `event` is the newest one asked for. Thread-safe; a concurrent caller waits for
  // an encode in progress instead of repeating it.
  std::shared_ptr<const v1::SessionEvent> get(std::shared_ptr<const v1::SessionEvent> event,
                                              const v1::FrameFormat& format);
  int encodes() const;  // encodes done so far (tests)

 private:
  mutable std::mutex mutex_;
  std::weak_ptr<const v1::SessionEvent> source_;
  std::map<int, std::shared_ptr<const v1::SessionEvent>> by_encoding_;
  int encodes_ = 0;
};

}  // namespace hdeform::service
