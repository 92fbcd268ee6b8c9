#include "horus/raw_topic.hpp"

#include <cstring>
#include <utility>

#include "horus/detail/message_count.hpp"
#include "horus/topic_registry.hpp"

namespace horus {

TypeIdentity type_identity_of(const TopicInfo& info) {
  TypeIdentity identity;
  identity.name = info.type_name;
  identity.fingerprint = info.fingerprint;
  identity.schema = info.schema;
  identity.is_pod = info.is_pod;
  identity.size = info.is_pod ? info.max_message_size : 0;
  identity.description = info.description;
  return identity;
}

std::unique_ptr<RawTopic> RawTopic::open_recorded(const TopicInfo& info,
                                                  const std::string& namespace_name) {
  TopicOptions options;
  options.capacity = info.capacity;
  options.max_message_size = info.max_message_size;
  options.namespace_name = namespace_name;
  return std::make_unique<RawTopic>(info.name, type_identity_of(info), options);
}

RawTopic::RawTopic(std::string name, TypeIdentity type, const TopicOptions& options)
    : name_(std::move(name)),
      type_(std::move(type)),
      endpoint_(detail::ShmSegment::open_topic(
          name_,
          detail::TypeDescriptor{type_.name, type_.fingerprint, type_.schema, type_.is_pod,
                                 type_.is_pod ? type_.size : 0, type_.alignment, type_.description},
          detail::SegmentOptions{options.capacity, options.max_message_size, options.mode,
                                 options.namespace_name, options.single_publisher})),
      buffer_(endpoint_.ring().payload_capacity),
      spare_(type_.is_pod ? type_.size : 0) {}

bool RawTopic::send(std::span<const std::byte> bytes) noexcept {
  if (bytes.size() > endpoint_.ring().payload_capacity) {
    // Refused before claiming: no slot is taken and given back for a message that cannot fit.
    endpoint_.mark(detail::kRolePublisher);
    endpoint_.count_oversized();
    return false;
  }
  const bool sent = endpoint_.send([&](std::byte* payload) noexcept {
    std::memcpy(payload, bytes.data(), bytes.size());
    return static_cast<std::uint32_t>(bytes.size());
  });
  if (sent) {
    detail::count_sent(this, name_);  // the running node's messages_sent, as Topic<T>::send counts
  }
  return sent;
}

std::byte* RawTopic::loan() noexcept {
  release_loan();
  endpoint_.mark(detail::kRolePublisher);
  loan_ = endpoint_.claim_slot();
  loaned_ = true;
  return loan_.slot != nullptr ? endpoint_.ring().payload(*loan_.slot) : spare_.data();
}

bool RawTopic::publish() noexcept {
  if (!loaned_) {
    return false;
  }
  loaned_ = false;
  if (detail::finish_claim(endpoint_.ring(), loan_, static_cast<std::uint32_t>(type_.size))) {
    detail::count_sent(this, name_);
    return true;
  }
  endpoint_.count_send_failure();
  return false;
}

void RawTopic::release_loan() noexcept {
  if (!loaned_) {
    return;
  }
  loaned_ = false;
  detail::finish_claim(endpoint_.ring(), loan_, detail::kReleasedSlot);
}

bool RawTopic::copy_received(const std::byte* payload, std::uint32_t size) noexcept {
  if (size > buffer_.size() || (type_.is_pod && size != type_.size)) {
    return false;
  }
  std::memcpy(buffer_.data(), payload, size);
  return true;
}

std::ptrdiff_t RawTopic::receive(bool check_stall) noexcept {
  std::ptrdiff_t length = -1;
  const bool got = endpoint_.receive(
      check_stall,
      [&](const std::byte* payload, std::uint32_t size) {
        if (!copy_received(payload, size)) {
          return false;
        }
        length = size;
        return true;
      },
      []() noexcept { return true; });
  if (!got) {
    return -1;
  }
  // The running node's messages_received, as Topic<T> counts.
  detail::count_received(this, name_, endpoint_.next_ticket());
  return length;
}

std::ptrdiff_t RawTopic::try_recv() noexcept { return receive(false); }

std::ptrdiff_t RawTopic::recv(std::chrono::nanoseconds timeout) noexcept {
  std::ptrdiff_t got = -1;
  endpoint_.receive_within(timeout, [&](bool check_stall) noexcept {
    got = receive(check_stall);
    return got >= 0;
  });
  return got;
}

std::optional<TopicWaitWord> RawTopic::begin_wait() noexcept {
  end_wait();
  const auto announcement = endpoint_.announce_wait();
  if (!announcement) {
    return std::nullopt;
  }
  waiting_ = announcement->counted;
  return TopicWaitWord{&endpoint_.ring().control->notify, announcement->seen,
                       announcement->recheck_after};
}

void RawTopic::end_wait() noexcept {
  if (waiting_) {
    waiting_ = false;
    endpoint_.withdraw_wait();
  }
}

std::ptrdiff_t RawTopic::read_latest() noexcept {
  std::ptrdiff_t length = -1;
  detail::ring_read_latest(endpoint_.ring(), [&](const std::byte* payload, std::uint32_t size) {
    if (!copy_received(payload, size)) {
      return false;
    }
    length = size;
    return true;
  });
  return length;
}

}  // namespace horus
