#include "erased_topic.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

#include "horus/detail/futex.hpp"

namespace horus::python {

namespace {
// As Topic<T>::kSlice: how long a sleeper that may have missed its wake-up sleeps at a time.
constexpr std::chrono::nanoseconds kSlice = std::chrono::microseconds(50);
}  // namespace

ErasedTopic::ErasedTopic(std::string name, ErasedType type, const TopicOptions& options)
    : name_(std::move(name)),
      type_(std::move(type)),
      segment_(detail::ShmSegment::open_topic(
          name_,
          detail::TypeDescriptor{type_.name, type_.fingerprint, type_.schema, type_.is_pod,
                                 type_.is_pod ? type_.size : 0, type_.alignment},
          detail::SegmentOptions{options.capacity, options.max_message_size, options.mode,
                                 options.namespace_name, options.single_publisher})),
      ring_(segment_.ring()),
      buffer_(ring_.payload_capacity),
      spare_(type_.is_pod ? type_.size : 0) {
  cursor_.next = detail::ring_written(ring_);
}

void ErasedTopic::mark(std::uint32_t role) noexcept {
  if ((roles_ & role) == 0) {
    roles_ |= role;
    segment_.add_role(role);
  }
}

detail::Claim ErasedTopic::claim_slot() noexcept {
  if (ring_.shared_base == detail::kUnshared) {
    if (lease_.held() || lease_.acquire(ring_)) {
      return lease_.claim(ring_);
    }
    if (ring_.single_publisher) {
      ++stats_.not_the_publisher;
      return detail::Claim{nullptr, 0, false, false};
    }
    if (!detail::ring_share(ring_)) {
      return detail::Claim{nullptr, 0, false, false};
    }
  }
  return detail::ring_claim(ring_, detail::this_pid());
}

bool ErasedTopic::send(std::span<const std::byte> bytes) noexcept {
  mark(detail::kRolePublisher);
  const std::uint32_t sent = detail::send_stamp_s();
  if (bytes.size() > ring_.payload_capacity) {
    ++stats_.send_failures;
    ++stats_.oversized;
    return false;
  }
  const detail::Claim claim = claim_slot();
  if (claim.slot == nullptr) {
    detail::ring_refused(ring_, claim);
    ++stats_.send_failures;
    return false;
  }
  std::memcpy(ring_.payload(*claim.slot), bytes.data(), bytes.size());
  detail::ring_commit(ring_, claim, static_cast<std::uint32_t>(bytes.size()), sent);
  return true;
}

std::byte* ErasedTopic::loan() noexcept {
  release_loan();
  mark(detail::kRolePublisher);
  loan_ = claim_slot();
  loaned_ = true;
  return loan_.slot != nullptr ? ring_.payload(*loan_.slot) : spare_.data();
}

bool ErasedTopic::publish() noexcept {
  if (!loaned_) {
    return false;
  }
  loaned_ = false;
  if (loan_.slot != nullptr) {
    detail::ring_commit(ring_, loan_, static_cast<std::uint32_t>(type_.size),
                        detail::send_stamp_s());
    loan_.slot = nullptr;
    return true;
  }
  detail::ring_refused(ring_, loan_);
  ++stats_.send_failures;
  return false;
}

void ErasedTopic::release_loan() noexcept {
  if (!loaned_) {
    return;
  }
  loaned_ = false;
  if (loan_.slot != nullptr) {
    detail::ring_commit(ring_, loan_, detail::kReleasedSlot, detail::send_stamp_s());
    loan_.slot = nullptr;
  } else {
    detail::ring_refused(ring_, loan_);
  }
}

std::ptrdiff_t ErasedTopic::receive(bool check_stall) noexcept {
  mark(detail::kRoleSubscriber);
  for (;;) {
    std::ptrdiff_t length = -1;
    const int got = detail::ring_read(
        ring_, cursor_, check_stall, [&](const std::byte* payload, std::uint32_t size) {
          if (size > buffer_.size() || (type_.is_pod && size != type_.size)) {
            return false;
          }
          std::memcpy(buffer_.data(), payload, size);
          length = size;
          return true;
        });
    if (got == 0) {
      return -1;
    }
    if (got > 0) {
      return length;
    }
    ++stats_.invalid;
  }
}

std::ptrdiff_t ErasedTopic::try_recv() noexcept { return receive(false); }

std::ptrdiff_t ErasedTopic::recv(std::chrono::nanoseconds timeout) noexcept {
  std::ptrdiff_t got = receive(false);
  if (got >= 0) {
    return got;
  }
  detail::RingControl& control = *ring_.control;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const std::uint32_t seen = control.notify.load(std::memory_order_seq_cst);
    const std::uint64_t claimed_before = segment_.announce_sleeper();
    const bool announced = detail::ring_sleeper_barrier(control);
    got = receive(true);
    const auto remaining = deadline - std::chrono::steady_clock::now();
    if (got < 0 && remaining > std::chrono::nanoseconds::zero()) {
      const bool unannounced =
          claimed_before == UINT64_MAX || !announced || cursor_.next < claimed_before;
      detail::futex_wait(
          control.notify, seen,
          unannounced ? std::min<std::chrono::nanoseconds>(remaining, kSlice) : remaining);
    }
    if (claimed_before != UINT64_MAX) {
      segment_.withdraw_sleeper();
    }
    if (got >= 0 || remaining <= std::chrono::nanoseconds::zero()) {
      return got;
    }
  }
}

std::ptrdiff_t ErasedTopic::read_latest() noexcept {
  std::ptrdiff_t length = -1;
  detail::ring_read_latest(ring_, [&](const std::byte* payload, std::uint32_t size) {
    if (size > buffer_.size() || (type_.is_pod && size != type_.size)) {
      return false;
    }
    std::memcpy(buffer_.data(), payload, size);
    length = size;
    return true;
  });
  return length;
}

}  // namespace horus::python
