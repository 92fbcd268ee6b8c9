// horus::TopicStats: the per-handle counters of a topic (Topic<T>::stats()).
#pragma once

#include <cstdint>

namespace horus {

/// Per-handle counters: nothing fails silently.
struct TopicStats {
  /// Messages this handle never received because it fell more than `capacity` behind
  /// (or their publisher died while writing them).
  std::uint64_t lost = 0;
  /// send()/publish() calls that published nothing (oversized, or the slot was held by a
  /// publisher stalled for a whole lap of the ring).
  std::uint64_t send_failures = 0;
  /// The part of send_failures due to messages over max_message_size.
  std::uint64_t oversized = 0;
  /// The part of send_failures on a single-publisher topic whose lease another live handle
  /// holds.
  std::uint64_t not_the_publisher = 0;
  /// Received slots whose content did not decode as T (a corrupted segment).
  std::uint64_t invalid = 0;
};

}  // namespace horus
