// Waiting on one local topic from an event loop, without a thread of its own: the topic's futex
// wait (RawTopic::begin_wait) is submitted to an io_uring of the watch's, whose descriptor turns
// readable when the wait ends, so the loop watches it beside its sockets (epoll, kj's
// FdObserver) and a message costs no hand-over between threads. Needs io_uring futex waits
// (Linux 6.7+, io_uring not disabled by a sysctl or a seccomp filter): supported() says; where it
// says no, a thread blocking in RawTopic::recv hands the messages over instead.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "horus/raw_topic.hpp"

namespace horus::bridge {

/// Where a bridge's readers wait on their topics, for the whole process.
enum class TopicWait {
  /// In the event loop, through a TopicWatch per topic (io_uring futex waits).
  EventLoop,
  /// On a thread per topic, which hands each message to the event loop.
  ReaderThread,
};

/// The event loop where TopicWatch::supported(), unless the environment variable `opt_out` is
/// "1" (HORUS_REMOTE_NO_IO_URING, HORUS_VIEW_NO_IO_URING: to test the threads, and to compare the
/// two).
TopicWait choose_topic_wait(const char* opt_out) noexcept;
/// Why a bridge waits with reader threads: `opt_out`=1 was asked, or the kernel offers no io_uring
/// futex waits (empty when it waits in the event loop).
std::string reader_threads_reason(const char* opt_out);

/// Watches one RawTopic. The loop, on each readable fd() and once at the start:
///
///     watch.complete();
///     while (topic.try_recv() >= 0) { ... }
///     if (!watch.arm()) { ... read again: a message came meanwhile }
///
/// arm(), complete() and the destructor run on the loop's thread: the kernel finishes an
/// io_uring futex wait in the task that submitted it, interrupting that task's sleep to do so
/// (an epoll_wait then returns EINTR, which event loops retry).
class TopicWatch {
 public:
  /// Whether io_uring futex waits work in this process: probed once (a ring of its own, the
  /// kernel's list of supported operations, and a wait on a word that differs from the value
  /// given, which must end at once with EAGAIN). False on older kernels and where io_uring is
  /// refused; never throws.
  static bool supported() noexcept;

  /// Watches `topic`, which must outlive the watch. Throws horus::Error when !supported() or
  /// the ring cannot be set up (the message says which and why).
  explicit TopicWatch(RawTopic& topic);
  TopicWatch(const TopicWatch&) = delete;
  TopicWatch& operator=(const TopicWatch&) = delete;
  /// Cancels a wait in flight, withdraws its announcement on the topic and closes the ring
  /// (take fd() out of the loop first).
  ~TopicWatch();

  /// The ring's descriptor: readable (POLLIN) once an armed wait has ended.
  int fd() const noexcept;
  /// False: the topic has something to read now, and nothing is armed. True: a wait is armed
  /// (or already was); when fd() turns readable, complete() and read. Throws horus::Error when
  /// the kernel refuses the submission.
  bool arm();
  /// Ends the wait: takes its completions (cancelling a wait that has not ended, as on a
  /// spurious wake-up of the loop) and withdraws its announcement on the topic. Does nothing
  /// when nothing is armed.
  void complete() noexcept;
  bool armed() const noexcept { return armed_; }

 private:
  class Ring;

  /// The probe behind supported(): the operations are there, and a futex wait on a word that
  /// differs from the value given ends at once with EAGAIN (a kernel that slept instead is cut
  /// short by a linked timeout, and counts as unsupported).
  static bool probe_futex_waits();
  /// Asks the kernel to cancel the current wait; whether it took the request (whose own
  /// completion then follows).
  bool cancel_wait() noexcept;
  /// Takes every completion queued now, counting those of the current wait.
  void take_completions() noexcept;

  RawTopic& topic_;
  std::unique_ptr<Ring> ring_;
  /// A wait was submitted and complete() has not ended it.
  bool armed_ = false;
  /// The futex wait's own completion has been taken.
  bool wait_ended_ = false;
  /// Completions of the current wait still to come (the wait, its timeout, a cancellation).
  unsigned in_flight_ = 0;
  /// Tags the current wait's completions, so that one left over from an earlier wait whose
  /// completions were not all taken (a failed cancellation) is not mistaken for them.
  std::uint64_t generation_ = 0;
};

}  // namespace horus::bridge
