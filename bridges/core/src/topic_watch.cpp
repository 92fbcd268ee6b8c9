#include "horus/bridge/topic_watch.hpp"

#include <linux/futex.h>
#include <linux/io_uring.h>
#include <linux/time_types.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>
#include <optional>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "horus/error.hpp"

namespace horus::bridge {
namespace {

// The io_uring futex wait of Linux 6.7: IORING_OP_FUTEX_WAIT in enum io_uring_op
// (include/uapi/linux/io_uring.h) and FUTEX2_SIZE_U32 (include/uapi/linux/futex.h). Their values
// are the kernel's ABI; Debian 12's linux-libc-dev (6.1) defines neither yet.
constexpr std::uint8_t kOpFutexWait = 51;
constexpr std::uint32_t kFutex2SizeU32 = 0x02;
#ifdef FUTEX2_SIZE_U32
static_assert(FUTEX2_SIZE_U32 == kFutex2SizeU32);
#endif

/// Submission and completion entries: a wait, its timeout and a cancellation at most.
constexpr unsigned kEntries = 4;

/// What a completion is for, in the low bits of its user_data (the wait's generation above).
enum Tag : std::uint64_t { kWaitTag = 0, kTimeoutTag = 1, kCancelTag = 2 };
constexpr std::uint64_t kTagBits = 2;
constexpr std::uint64_t kTagMask = (std::uint64_t{1} << kTagBits) - 1;

std::string error_text(int error) { return std::system_category().message(error); }

__kernel_timespec to_timespec(std::chrono::nanoseconds duration) {
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(duration);
  return __kernel_timespec{seconds.count(), (duration - seconds).count()};
}

/// Fills `sqe` with a futex wait on `word` while it holds `expected`. Shared (no FUTEX2_PRIVATE):
/// the topic's word lives in a segment that other processes map, and they wake it.
void prepare_futex_wait(io_uring_sqe& sqe, const std::atomic<std::uint32_t>* word,
                        std::uint32_t expected, std::uint64_t user_data) {
  sqe.opcode = kOpFutexWait;
  sqe.fd = static_cast<std::int32_t>(kFutex2SizeU32);
  sqe.addr = reinterpret_cast<std::uintptr_t>(word);
  sqe.addr2 = expected;
  sqe.addr3 = FUTEX_BITSET_MATCH_ANY;
  sqe.user_data = user_data;
}

/// Fills `sqe` with a timeout for the entry before it, which carries IOSQE_IO_LINK. The kernel
/// copies `timeout` when the entry is submitted.
void prepare_link_timeout(io_uring_sqe& sqe, const __kernel_timespec& timeout,
                          std::uint64_t user_data) {
  sqe.opcode = IORING_OP_LINK_TIMEOUT;
  sqe.fd = -1;
  sqe.addr = reinterpret_cast<std::uintptr_t>(&timeout);
  sqe.len = 1;
  sqe.user_data = user_data;
}

}  // namespace

/// An io_uring of a few entries through the raw system calls, its rings mapped.
class TopicWatch::Ring {
 public:
  explicit Ring(unsigned entries) {
    io_uring_params params{};
    // A completion interrupts a sleeping loop all the same; a running one is not sent an
    // interrupt, and takes it when it next enters the kernel (its next epoll_wait). Not
    // IORING_SETUP_DEFER_TASKRUN: its completions wait for an io_uring_enter, so the descriptor
    // never turns readable for a loop asleep in epoll_wait (tried on 6.18).
    params.flags = IORING_SETUP_COOP_TASKRUN;
    fd_ = static_cast<int>(syscall(SYS_io_uring_setup, entries, &params));
    if (fd_ < 0) {
      throw Error("io_uring_setup: " + error_text(errno));
    }
    try {
      map(params);
    } catch (...) {
      release();
      throw;
    }
  }
  Ring(const Ring&) = delete;
  Ring& operator=(const Ring&) = delete;
  ~Ring() { release(); }

  int fd() const noexcept { return fd_; }

  /// Whether the kernel supports operation `op`.
  bool supports(std::uint8_t op) const {
    std::vector<std::byte> storage(sizeof(io_uring_probe) + 256 * sizeof(io_uring_probe_op));
    auto* probe = reinterpret_cast<io_uring_probe*>(storage.data());
    if (syscall(SYS_io_uring_register, fd_, IORING_REGISTER_PROBE, probe, 256) < 0) {
      return false;
    }
    return op <= probe->last_op && op < probe->ops_len &&
           (probe->ops[op].flags & IO_URING_OP_SUPPORTED) != 0;
  }

  /// A cleared submission entry, queued for the next submit().
  io_uring_sqe& prepare() noexcept {
    io_uring_sqe& sqe = sqes_[(sq_tail_ + queued_) & sq_mask_];
    std::memset(&sqe, 0, sizeof sqe);
    ++queued_;
    return sqe;
  }

  /// Hands the prepared entries to the kernel: how many it took, or -errno (then it took none
  /// and they are dropped).
  int submit() noexcept {
    const unsigned count = std::exchange(queued_, 0U);
    std::atomic_ref<unsigned>(*sq_tail_shared_).store(sq_tail_ + count, std::memory_order_release);
    const long taken = syscall(SYS_io_uring_enter, fd_, count, 0, 0, nullptr, 0);
    if (taken < 0) {
      const int error = errno;
      std::atomic_ref<unsigned>(*sq_tail_shared_).store(sq_tail_, std::memory_order_release);
      return -error;
    }
    sq_tail_ += count;
    return static_cast<int>(taken);
  }

  /// Calls `take(cqe)` for every completion queued now.
  template <class Take>
  void reap(Take&& take) noexcept {
    unsigned head = std::atomic_ref<unsigned>(*cq_head_).load(std::memory_order_relaxed);
    const unsigned tail = std::atomic_ref<unsigned>(*cq_tail_).load(std::memory_order_acquire);
    for (; head != tail; ++head) {
      take(cqes_[head & cq_mask_]);
    }
    std::atomic_ref<unsigned>(*cq_head_).store(head, std::memory_order_release);
  }

  /// Sleeps until a completion is queued. False when the kernel refused (not for a signal).
  bool wait_for_completion() noexcept {
    for (;;) {
      if (syscall(SYS_io_uring_enter, fd_, 0, 1, IORING_ENTER_GETEVENTS, nullptr, 0) >= 0) {
        return true;
      }
      if (errno != EINTR) {
        return false;
      }
    }
  }

 private:
  void map(const io_uring_params& params) {
    sq_map_size_ = params.sq_off.array + params.sq_entries * sizeof(unsigned);
    cq_map_size_ = params.cq_off.cqes + params.cq_entries * sizeof(io_uring_cqe);
    const bool single = (params.features & IORING_FEAT_SINGLE_MMAP) != 0;
    if (single) {
      sq_map_size_ = cq_map_size_ = std::max(sq_map_size_, cq_map_size_);
    }
    sq_map_ = map_region(sq_map_size_, IORING_OFF_SQ_RING, "submission ring");
    cq_map_ = single ? sq_map_ : map_region(cq_map_size_, IORING_OFF_CQ_RING, "completion ring");
    sqes_size_ = params.sq_entries * sizeof(io_uring_sqe);
    sqes_ =
        static_cast<io_uring_sqe*>(map_region(sqes_size_, IORING_OFF_SQES, "submission entries"));

    auto* sq = static_cast<std::byte*>(sq_map_);
    auto* cq = static_cast<std::byte*>(cq_map_);
    sq_tail_shared_ = reinterpret_cast<unsigned*>(sq + params.sq_off.tail);
    sq_tail_ = *sq_tail_shared_;
    sq_mask_ = *reinterpret_cast<unsigned*>(sq + params.sq_off.ring_mask);
    // Entry i of the submission array always names submission entry i: entries are queued in order.
    auto* array = reinterpret_cast<unsigned*>(sq + params.sq_off.array);
    for (unsigned i = 0; i < params.sq_entries; ++i) {
      array[i] = i;
    }
    cq_head_ = reinterpret_cast<unsigned*>(cq + params.cq_off.head);
    cq_tail_ = reinterpret_cast<unsigned*>(cq + params.cq_off.tail);
    cq_mask_ = *reinterpret_cast<unsigned*>(cq + params.cq_off.ring_mask);
    cqes_ = reinterpret_cast<io_uring_cqe*>(cq + params.cq_off.cqes);
  }

  void* map_region(std::size_t size, off_t offset, const char* what) const {
    void* region =
        mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, fd_, offset);
    if (region == MAP_FAILED) {
      throw Error(std::string("mapping the io_uring ") + what + ": " + error_text(errno));
    }
    return region;
  }

  void release() noexcept {
    if (sqes_ != nullptr) {
      munmap(sqes_, sqes_size_);
    }
    if (cq_map_ != nullptr && cq_map_ != sq_map_) {
      munmap(cq_map_, cq_map_size_);
    }
    if (sq_map_ != nullptr) {
      munmap(sq_map_, sq_map_size_);
    }
    if (fd_ >= 0) {
      close(fd_);
    }
  }

  int fd_ = -1;
  void* sq_map_ = nullptr;
  std::size_t sq_map_size_ = 0;
  void* cq_map_ = nullptr;
  std::size_t cq_map_size_ = 0;
  io_uring_sqe* sqes_ = nullptr;
  std::size_t sqes_size_ = 0;
  unsigned* sq_tail_shared_ = nullptr;
  /// The submission tail as this process last published it (only this process writes it).
  unsigned sq_tail_ = 0;
  unsigned sq_mask_ = 0;
  /// Entries prepared since the last submit().
  unsigned queued_ = 0;
  unsigned* cq_head_ = nullptr;
  unsigned* cq_tail_ = nullptr;
  unsigned cq_mask_ = 0;
  io_uring_cqe* cqes_ = nullptr;
};

bool TopicWatch::probe_futex_waits() {
  Ring ring(kEntries);
  if (!ring.supports(kOpFutexWait) || !ring.supports(IORING_OP_LINK_TIMEOUT) ||
      !ring.supports(IORING_OP_ASYNC_CANCEL)) {
    return false;
  }
  const std::atomic<std::uint32_t> word{1};
  io_uring_sqe& wait = ring.prepare();
  prepare_futex_wait(wait, &word, 0, kWaitTag);
  wait.flags |= IOSQE_IO_LINK;
  const __kernel_timespec limit = to_timespec(std::chrono::seconds(1));
  prepare_link_timeout(ring.prepare(), limit, kTimeoutTag);
  if (ring.submit() != 2) {
    return false;
  }
  std::optional<std::int32_t> wait_result;
  int completions = 0;
  while (completions < 2) {
    if (!ring.wait_for_completion()) {
      return false;
    }
    ring.reap([&](const io_uring_cqe& cqe) {
      ++completions;
      if (cqe.user_data == kWaitTag) {
        wait_result = cqe.res;
      }
    });
  }
  return wait_result == -EAGAIN;
}

namespace {

bool opted_out(const char* opt_out) noexcept {
  const char* value = std::getenv(opt_out);
  return value != nullptr && std::string_view(value) == "1";
}

}  // namespace

TopicWait choose_topic_wait(const char* opt_out) noexcept {
  return !opted_out(opt_out) && TopicWatch::supported() ? TopicWait::EventLoop
                                                        : TopicWait::ReaderThread;
}

std::string reader_threads_reason(const char* opt_out) {
  if (opted_out(opt_out)) return std::string(opt_out) + "=1";
  if (!TopicWatch::supported()) {
    return "no io_uring futex waits here: they need Linux 6.7 or later with io_uring allowed";
  }
  return {};
}

bool TopicWatch::supported() noexcept {
  static const bool works = [] {
    try {
      return probe_futex_waits();
    } catch (const std::exception&) {
      return false;  // io_uring_setup refused: an old kernel, a sysctl, a seccomp filter
    }
  }();
  return works;
}

TopicWatch::TopicWatch(RawTopic& topic) : topic_(topic) {
  if (!supported()) {
    throw Error("topic '" + topic.name() +
                "': io_uring futex waits are not available here (they need Linux 6.7 or later "
                "with io_uring allowed); wait in a thread blocking in RawTopic::recv instead");
  }
  try {
    ring_ = std::make_unique<Ring>(kEntries);
  } catch (const Error& error) {
    throw Error("topic '" + topic.name() + "': watching it from an event loop: " + error.what());
  }
}

TopicWatch::~TopicWatch() {
  if (!armed_) {
    return;
  }
  take_completions();
  if (!wait_ended_) {
    // Takes the wait off the futex before the topic's announcement goes; closing the ring then
    // drops the completions still to come.
    cancel_wait();
  }
  topic_.end_wait();
}

int TopicWatch::fd() const noexcept { return ring_->fd(); }

bool TopicWatch::arm() {
  if (armed_) {
    return true;
  }
  const std::optional<TopicWaitWord> word = topic_.begin_wait();
  if (!word) {
    return false;
  }
  ++generation_;
  io_uring_sqe& wait = ring_->prepare();
  prepare_futex_wait(wait, word->word, word->expected, generation_ << kTagBits | kWaitTag);
  unsigned entries = 1;
  // Outlives submit(), which is when the kernel copies it.
  const __kernel_timespec recheck = to_timespec(word->recheck_after);
  if (word->recheck_after > std::chrono::nanoseconds::zero()) {
    wait.flags |= IOSQE_IO_LINK;
    prepare_link_timeout(ring_->prepare(), recheck, generation_ << kTagBits | kTimeoutTag);
    ++entries;
  }
  const int taken = ring_->submit();
  if (taken != static_cast<int>(entries)) {
    topic_.end_wait();
    throw Error("topic '" + topic_.name() + "': submitting its futex wait to io_uring: " +
                (taken < 0 ? error_text(-taken)
                           : "the kernel took " + std::to_string(taken) + " of " +
                                 std::to_string(entries) + " entries"));
  }
  armed_ = true;
  wait_ended_ = false;
  in_flight_ = entries;
  return true;
}

void TopicWatch::complete() noexcept {
  take_completions();
  if (!armed_) {
    return;
  }
  if (!wait_ended_) {
    if (cancel_wait()) {
      ++in_flight_;
    } else {
      // The wait stays in the kernel; its completions come later, under an older generation.
      in_flight_ = 0;
    }
  }
  // The rest follow at once: a linked timeout is cancelled when its wait ends and the other way
  // round, and a cancellation ends the wait.
  while (in_flight_ > 0 && ring_->wait_for_completion()) {
    take_completions();
  }
  armed_ = false;
  topic_.end_wait();
}

bool TopicWatch::cancel_wait() noexcept {
  io_uring_sqe& cancel = ring_->prepare();
  cancel.opcode = IORING_OP_ASYNC_CANCEL;
  cancel.fd = -1;
  cancel.addr = generation_ << kTagBits | kWaitTag;
  cancel.user_data = generation_ << kTagBits | kCancelTag;
  return ring_->submit() == 1;
}

void TopicWatch::take_completions() noexcept {
  ring_->reap([&](const io_uring_cqe& cqe) {
    if (cqe.user_data >> kTagBits != generation_ || in_flight_ == 0) {
      return;  // left over from an earlier wait
    }
    --in_flight_;
    if ((cqe.user_data & kTagMask) == kWaitTag) {
      wait_ended_ = true;
    }
  });
}

}  // namespace horus::bridge
