// The shape of a bridge's per-topic worker: one thread that moves a topic's frames (a message's
// bytes, or a pool descriptor with its block's data) between the local HORUS topic and the other
// side, with its stop, its counters and its failure lines. Each bridge gives it a loop (the DDS
// bridge's export and import pumps, bridges/dds/; the remote link's forwarder, bridges/remote/),
// which reads a local topic through a FrameSource (frame_source.hpp).
// Failures follow docs/dds-bridge.md "When something fails": one line on stderr per failure with
// the topic's running count, an operation retried after kRetry with the same frame (nothing is
// reordered), a frame that cannot be converted or delivered dropped. The thread never dies of a
// failure; anything else its loop throws (a bug) ends it and shows in broken(), which the bridge
// turns into its own stop with status 1.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace horus::bridge {

class Forwarder {
 public:
  static constexpr std::chrono::milliseconds kRetry{500};

  Forwarder(const Forwarder&) = delete;
  Forwarder& operator=(const Forwarder&) = delete;
  /// Stops and joins the thread.
  virtual ~Forwarder();

  /// Ends the loop within about kPoll; returns once the thread has.
  void stop();
  std::uint64_t carried() const noexcept { return carried_.load(std::memory_order_relaxed); }
  std::uint64_t failures() const noexcept { return failures_.load(std::memory_order_relaxed); }
  /// Why the thread ended on its own (a bug in the bridge), or empty while it runs or stopped.
  std::string broken() const;

 protected:
  /// How often a waiting loop looks at its stop.
  static constexpr std::chrono::milliseconds kPoll{100};

  /// `label` starts each failure line (`horus bridge: topic 'cmd_vel'`); `keep_alive`: what the
  /// thread uses of the other side (an endpoint), released after the thread ends.
  Forwarder(std::string label, std::shared_ptr<void> keep_alive);
  /// Runs `loop` on the thread; each derived constructor calls it last.
  void start(std::function<void()> loop);
  bool stopping() const noexcept { return stopping_.load(std::memory_order_relaxed); }
  /// One line on stderr: `<label>: <error> (failure N of it); <then>`.
  void failed(const std::string& error, const char* then);
  /// Counts one more failure; its running count.
  std::uint64_t count_failure() noexcept {
    return failures_.fetch_add(1, std::memory_order_relaxed) + 1;
  }
  /// One line on stderr, whole: `<label>: <text>` (nothing for an empty text).
  void say(const std::string& text) const;
  /// Sleeps `how_long`, or less when stopped.
  void pause(std::chrono::milliseconds how_long = kRetry);
  void count_carried() noexcept { carried_.fetch_add(1, std::memory_order_relaxed); }
  /// Runs `work`; what it throws (a bug) goes to broken() and stops the loop.
  void guarded(const std::function<void()>& work) noexcept;

 private:
  std::string label_;
  std::shared_ptr<void> keep_alive_;
  std::atomic<bool> stopping_{false};
  std::atomic<std::uint64_t> carried_{0};
  std::atomic<std::uint64_t> failures_{0};
  mutable std::mutex mutex_;
  std::condition_variable woken_;
  std::string broken_;
  std::thread thread_;
};

}  // namespace horus::bridge
