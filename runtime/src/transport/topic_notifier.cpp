// TopicWaitSet and TopicNotifier: futex sleeps on topics' control pages, whatever their types.
#include <linux/futex.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <ctime>
#include <string>

#include "horus/detail/futex.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"
#include "horus/internal/topic_notifier.hpp"
#include "horus/internal/topic_wait_set.hpp"

namespace horus::detail {

namespace {

/// Sleep slice while a publisher that may not know about this sleeper is mid-commit.
constexpr std::chrono::nanoseconds kSlice = std::chrono::microseconds(50);
/// How long such a publisher is waited for in slices before sleeping until the timeout (the
/// commit counter is a plain store, so with racing publishers it can stay behind the claims).
constexpr std::chrono::nanoseconds kSlicedFor = std::chrono::milliseconds(2);

/// Sleeps until one of `words` differs from its expected value or `timeout` elapses.
void futex_wait_any(std::vector<futex_waitv>& words, std::chrono::nanoseconds timeout) noexcept {
  if (words.size() == 1) {
    futex_wait(*reinterpret_cast<std::atomic<std::uint32_t>*>(words[0].uaddr),
               static_cast<std::uint32_t>(words[0].val), timeout);
    return;
  }
  timespec deadline{};
  clock_gettime(CLOCK_MONOTONIC, &deadline);
  const auto total = std::chrono::nanoseconds(deadline.tv_nsec) + timeout;
  const auto secs = std::chrono::duration_cast<std::chrono::seconds>(total);
  deadline.tv_sec += static_cast<time_t>(secs.count());
  deadline.tv_nsec = static_cast<long>((total - secs).count());
  if (syscall(SYS_futex_waitv, words.data(), static_cast<unsigned>(words.size()), 0, &deadline,
              CLOCK_MONOTONIC) != 0 &&
      errno == ENOSYS) {
    // Kernels before 5.16: poll in slices rather than miss a topic.
    futex_wait(*reinterpret_cast<std::atomic<std::uint32_t>*>(words[0].uaddr),
               static_cast<std::uint32_t>(words[0].val), std::min(timeout, kSlice));
  }
}

}  // namespace

struct TopicWaitSet::State {
  struct Watched {
    ShmSegment segment;
    std::uint64_t last_seen;
  };
  std::vector<Watched> topics;
  std::vector<futex_waitv> words;
  std::vector<std::uint64_t> claimed_before;
  std::atomic<bool> interrupted{false};
  std::atomic<bool> waiting{false};
};

TopicWaitSet::TopicWaitSet(const std::vector<std::string>& topic_names,
                           std::string_view namespace_name)
    : state_(std::make_unique<State>()) {
  if (topic_names.empty() || topic_names.size() > FUTEX_WAITV_MAX) {
    throw Error("a topic wait set takes 1 to " + std::to_string(FUTEX_WAITV_MAX) + " topics, not " +
                std::to_string(topic_names.size()));
  }
  for (const std::string& name : topic_names) {
    ShmSegment segment =
        ShmSegment::open_control(name, SegmentOptions{0, 0, 0600, std::string(namespace_name)});
    const std::uint64_t seen = segment.control().ring.commits.load(std::memory_order_acquire);
    state_->topics.push_back({std::move(segment), seen});
  }
  state_->words.resize(topic_names.size());
  state_->claimed_before.resize(topic_names.size());
  for (std::size_t i = 0; i < topic_names.size(); ++i) {
    futex_waitv& word = state_->words[i];
    word = futex_waitv{};
    word.uaddr = reinterpret_cast<std::uintptr_t>(&state_->topics[i].segment.control().ring.notify);
    word.flags = FUTEX_32;
  }
}

TopicWaitSet::~TopicWaitSet() = default;

std::size_t TopicWaitSet::size() const noexcept { return state_->topics.size(); }

std::optional<std::size_t> TopicWaitSet::wait(std::chrono::nanoseconds timeout) noexcept {
  State& state = *state_;
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + timeout;
  state.waiting.store(true, std::memory_order_seq_cst);
  std::optional<std::size_t> arrived;
  auto check = [&state]() -> std::optional<std::size_t> {
    for (std::size_t i = 0; i < state.topics.size(); ++i) {
      State::Watched& topic = state.topics[i];
      const std::uint64_t commits =
          topic.segment.control().ring.commits.load(std::memory_order_seq_cst);
      if (commits != topic.last_seen) {
        topic.last_seen = commits;
        return i;
      }
    }
    return std::nullopt;
  };
  for (;;) {
    if (state.interrupted.exchange(false, std::memory_order_acq_rel)) {
      break;
    }
    if ((arrived = check())) {
      break;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) {
      break;
    }
    bool unannounced = false;
    const RingControl* leased = nullptr;
    for (std::size_t i = 0; i < state.topics.size(); ++i) {
      RingControl& control = state.topics[i].segment.control().ring;
      state.words[i].val = control.notify.load(std::memory_order_seq_cst);
      state.claimed_before[i] = state.topics[i].segment.announce_sleeper();
      if (ring_leased(control)) {
        leased = &control;
      }
    }
    // The barrier runs on every CPU, so one covers all the topics a lease holder publishes on.
    if (leased != nullptr && !ring_sleeper_barrier(*leased)) {
      unannounced = true;
    }
    // Re-checked after announcing this sleeper: later publishers will wake it, but one that
    // claimed before may be committing right now without knowing about it (not a lease
    // holder, past the barrier).
    for (std::size_t i = 0; i < state.topics.size(); ++i) {
      const RingControl& control = state.topics[i].segment.control().ring;
      const std::uint64_t committed = control.commits.load(std::memory_order_seq_cst);
      const std::uint64_t claimed = state.claimed_before[i];
      unannounced = unannounced || claimed == UINT64_MAX ||
                    (!ring_leased(control) && claimed != committed && now - start < kSlicedFor);
    }
    bool changed = false;
    for (const State::Watched& topic : state.topics) {
      changed = changed || topic.segment.control().ring.commits.load(std::memory_order_seq_cst) !=
                               topic.last_seen;
    }
    if (!changed) {
      futex_wait_any(state.words, unannounced ? std::min(deadline - now, kSlice) : deadline - now);
    }
    for (std::size_t i = 0; i < state.topics.size(); ++i) {
      if (state.claimed_before[i] != UINT64_MAX) {
        state.topics[i].segment.withdraw_sleeper();
      }
    }
  }
  state.waiting.store(false, std::memory_order_seq_cst);
  return arrived;
}

void TopicWaitSet::interrupt() noexcept {
  State& state = *state_;
  state.interrupted.store(true, std::memory_order_seq_cst);
  // The shared words cannot carry the interrupt without handing other processes a false
  // "message", so wake until the waiter has seen the flag (it consumes it on its way out).
  do {
    for (State::Watched& topic : state.topics) {
      futex_wake_all(topic.segment.control().ring.notify);
    }
    if (!state.waiting.load(std::memory_order_seq_cst)) {
      break;
    }
    sched_yield();
  } while (state.interrupted.load(std::memory_order_seq_cst));
}

struct TopicNotifier::State {
  explicit State(std::string_view topic_name) : set({std::string(topic_name)}) {}
  TopicWaitSet set;
};

TopicNotifier::TopicNotifier(std::string_view topic_name)
    : state_(std::make_unique<State>(topic_name)) {}

TopicNotifier::~TopicNotifier() = default;

bool TopicNotifier::wait(std::chrono::nanoseconds timeout) noexcept {
  return state_->set.wait(timeout).has_value();
}

void TopicNotifier::interrupt() noexcept { state_->set.interrupt(); }

}  // namespace horus::detail
