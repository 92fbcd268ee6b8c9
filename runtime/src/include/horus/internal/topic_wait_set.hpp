// horus::detail::TopicWaitSet: sleep until any of several topics (of any types) receives a
// message, in one futex_waitv(2) call: an event node triggered by several topics never polls.
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace horus::detail {

class TopicWaitSet {
 public:
  /// For the named topics (at most 128) of `namespace_name` (empty: the current namespace);
  /// each may not exist yet. Throws horus::Error for an invalid name or a corrupt segment.
  explicit TopicWaitSet(const std::vector<std::string>& topic_names,
                        std::string_view namespace_name = {});
  ~TopicWaitSet();
  TopicWaitSet(const TopicWaitSet&) = delete;
  TopicWaitSet& operator=(const TopicWaitSet&) = delete;

  /// Blocks until one of the topics receives a message sent after the previous wait() returned
  /// (or after construction), `timeout` elapses, or interrupt() is called. Returns the index of
  /// a topic that received one (the lowest, if several did); nullopt on timeout or interrupt.
  /// Call again to learn about the others: what arrived is remembered per topic.
  std::optional<std::size_t> wait(std::chrono::nanoseconds timeout) noexcept;
  /// Wakes a thread blocked in wait(), or makes the next wait() return at once.
  void interrupt() noexcept;

  std::size_t size() const noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace horus::detail
