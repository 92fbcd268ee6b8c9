// horus::Topic<T> for the pool-backed types (Image, DepthImage, PointCloud, Tensor): the ring
// carries the descriptor (a POD message), the data stays in its TensorPool block.
//
// A frame is kept alive while it is in the ring: send() takes a reference for it, given back
// when the ring has moved on by its capacity (the frames a subscriber can still reach), when the
// sending handle closes, or earlier by PoolExhaustion::DropOldest. A receiver takes its own
// reference before it looks at the data; a descriptor of a block freed or reused since, of
// another pool, or that does not fit its block is refused (counted in refused()) and skipped.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/detail/pool_mapping.hpp"
#include "horus/topic.hpp"

namespace horus {

/// The pool-backed types: a descriptor message and a reference on a pool block.
template <class T>
concept PoolValue = TopicValue<T> && requires {
  requires TypeInfo<T>::is_pool_backed;
  typename T::Descriptor;
};

/// Options for a topic of a pool-backed type: a small ring, as each frame in it holds a block.
inline TopicOptions pool_topic_options() {
  TopicOptions options;
  options.capacity = 4;
  return options;
}

template <PoolValue T>
class Topic<T> {
 public:
  using Descriptor = typename T::Descriptor;

  /// Opens (or creates) the topic; see Topic<T> of topic.hpp. The ring's capacity is also how
  /// many frames sent by this handle stay alive for subscribers that have not taken them yet.
  explicit Topic(std::string_view name, const TopicOptions& options = pool_topic_options())
      : inner_(name, options), namespace_(options.namespace_name), in_flight_(inner_.capacity()) {}

  Topic(Topic&&) noexcept = default;
  Topic& operator=(Topic&& other) noexcept {
    if (this != &other) {
      std::destroy_at(this);
      std::construct_at(this, std::move(other));
    }
    return *this;
  }
  Topic(const Topic&) = delete;
  Topic& operator=(const Topic&) = delete;
  /// The frames this handle sent that are still in flight are given back.
  ~Topic() {
    for (InFlight& frame : in_flight_) {
      frame.end();
    }
  }

  const std::string& name() const noexcept { return inner_.name(); }

  /// Publishes the descriptor of `value` (never its data). False (and a counter) when nothing
  /// was published, or `value` is empty (moved from).
  bool send(const T& value) noexcept {
    if (!value.valid()) {
      return false;
    }
    detail::PoolMapping* pool = value.pool_mapping();
    pool->begin_in_flight(value.block());
    if (!inner_.send(value.descriptor())) {
      pool->end_in_flight(value.block());
      return false;
    }
    InFlight& slot = in_flight_[next_in_flight_];
    next_in_flight_ = next_in_flight_ + 1 == in_flight_.size() ? 0 : next_in_flight_ + 1;
    slot.end();
    // Usually the same pool as the frame this slot held before: no reference count to touch.
    if (slot.pool != value.shared_pool_mapping()) {
      slot.pool = value.shared_pool_mapping();
    }
    slot.block = value.block();
    slot.live = true;
    return true;
  }

  /// The next frame for this handle, if one is there. Never blocks.
  std::optional<T> try_recv() noexcept {
    while (std::optional<Descriptor> descriptor = inner_.try_recv()) {
      if (std::optional<T> value = adopt(*descriptor)) {
        return value;
      }
    }
    return std::nullopt;
  }

  /// The next frame, waiting up to `timeout` for one.
  std::optional<T> recv(std::chrono::nanoseconds timeout) noexcept {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = deadline - std::chrono::steady_clock::now();
      std::optional<Descriptor> descriptor =
          inner_.recv(left > std::chrono::nanoseconds::zero() ? left : std::chrono::nanoseconds{0});
      if (!descriptor) {
        return std::nullopt;
      }
      if (std::optional<T> value = adopt(*descriptor)) {
        return value;
      }
    }
  }

  bool has_msg() const noexcept { return inner_.has_msg(); }

  /// The newest frame sent on the topic, if its block still holds it.
  std::optional<T> read_latest() const noexcept {
    if (std::optional<Descriptor> descriptor = inner_.read_latest()) {
      return adopt(*descriptor);
    }
    return std::nullopt;
  }

  /// Frames this handle lost by falling more than the capacity behind.
  std::uint64_t lost() const noexcept { return inner_.lost(); }
  /// Descriptors this handle refused: freed or reused blocks (e.g. dropped by the sender's
  /// DropOldest policy), other pools, or descriptors that do not fit their block.
  std::uint64_t refused() const noexcept { return refused_; }
  TopicStats stats() const noexcept { return inner_.stats(); }
  std::size_t capacity() const noexcept { return inner_.capacity(); }

 private:
  struct InFlight {
    std::shared_ptr<detail::PoolMapping> pool;
    msg::PoolBlock block{};
    bool live = false;
    void end() noexcept {
      if (live) {
        pool->end_in_flight(block);
        live = false;
      }
    }
  };

  std::optional<T> adopt(const Descriptor& descriptor) const noexcept {
    const std::shared_ptr<detail::PoolMapping>* pool = resolve(descriptor.block.pool_id);
    if (pool == nullptr || !T::valid_descriptor(descriptor, (*pool)->block_size()) ||
        !(*pool)->acquire(descriptor.block)) {
      ++refused_;
      return std::nullopt;
    }
    return T::received(detail::BlockRef(*pool, descriptor.block), descriptor);
  }

  /// The pool of a descriptor: the last one seen, else looked up (a slow path, once per pool).
  const std::shared_ptr<detail::PoolMapping>* resolve(std::uint64_t pool_id) const noexcept {
    if (last_pool_ && last_pool_->id() == pool_id) {
      return &last_pool_;
    }
    if (pool_id == unknown_pool_) {
      return nullptr;
    }
    try {
      if (std::shared_ptr<detail::PoolMapping> found = detail::find_pool(pool_id, namespace_)) {
        last_pool_ = std::move(found);
        return &last_pool_;
      }
    } catch (...) {
      // The pool folder cannot be read: no pool of it can be this one.
    }
    unknown_pool_ = pool_id;
    return nullptr;
  }

  Topic<Descriptor> inner_;
  std::string namespace_;
  std::vector<InFlight> in_flight_;
  std::size_t next_in_flight_ = 0;
  mutable std::shared_ptr<detail::PoolMapping> last_pool_;
  mutable std::uint64_t unknown_pool_ = 0;
  mutable std::uint64_t refused_ = 0;
};

}  // namespace horus
