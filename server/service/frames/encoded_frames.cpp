#include "service/frames/encoded_frames.h"

#include "service/frames/frame_encoding.h"

namespace hdeform::service {

std::shared_ptr<const v1::SessionEvent> EncodedFrameCache::get(
    std::shared_ptr<const v1::SessionEvent> event, const v1::FrameFormat& format) {
  if (!event->has_frame()) return event;
  const v1::FrameEncoding encoding = encoding_for(event->frame(), format);
  if (encoding == v1::FRAME_ENCODING_FLOAT32) return event;
  std::lock_guard lock(mutex_);
  if (source_.lock() != event) {  // a newer (or another) frame: the old encodings go
    by_encoding_.clear();
    source_ = event;
  }
  auto& slot = by_encoding_[encoding];
  if (!slot) {
    auto encoded = std::make_shared<v1::SessionEvent>();
    encode_frame_to(event->frame(), format, false, encoded->mutable_frame());
    slot = std::move(encoded);
    ++encodes_;
  }
  return slot;
}

int EncodedFrameCache::encodes() const {
  std::lock_guard lock(mutex_);
  return encodes_;
}

}  // namespace hdeform::service
