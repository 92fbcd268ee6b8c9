// horus::detail::TopicNotifier: sleep until a topic of any type receives a message.
//
// The scheduler's event nodes block on it instead of polling. It attaches to the topic's
// shared-memory wake word (a futex shared across processes), so it works before any publisher
// exists and whatever the message type is.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string_view>

namespace horus::detail {

class ShmSegment;

/// Lets a thread sleep until a topic (of any type) receives a message: the scheduler's event nodes.
class TopicNotifier {
 public:
  /// For the named topic in the current namespace; works before the topic exists (a publisher may
  /// come later).
  explicit TopicNotifier(std::string_view topic_name);
  ~TopicNotifier();
  TopicNotifier(const TopicNotifier&) = delete;
  TopicNotifier& operator=(const TopicNotifier&) = delete;
  /// Blocks until a message is sent after the previous wait() returned (or after construction),
  /// `timeout` elapses, or interrupt() is called. True when a message arrived.
  bool wait(std::chrono::nanoseconds timeout) noexcept;
  /// Wakes a thread blocked in wait() (shutdown).
  void interrupt() noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace horus::detail
