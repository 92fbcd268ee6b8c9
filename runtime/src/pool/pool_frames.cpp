// PoolFrames for Image, DepthImage, PointCloud and Tensor: a recorder takes a reference on the
// block a descriptor names the way a receiving Topic<T> does (pool_topic.hpp: valid_descriptor,
// then acquire), and a replay makes a frame the way a sending Topic<T> keeps one alive.
#include "horus/pool_frames.hpp"

#include <cstring>
#include <optional>
#include <vector>

#include "horus/depth_image.hpp"
#include "horus/image.hpp"
#include "horus/point_cloud.hpp"
#include "horus/tensor.hpp"
#include "horus/tensor_pool.hpp"

namespace horus::detail {
namespace {

template <class T>
class TypedPoolFrames final : public PoolFrames {
 public:
  using Descriptor = typename T::Descriptor;

  TypedPoolFrames(std::string namespace_name, std::size_t keep)
      : namespace_(std::move(namespace_name)), in_flight_(std::max<std::size_t>(keep, 1)) {}

  ~TypedPoolFrames() override {
    for (std::optional<msg::PoolBlock>& frame : in_flight_) {
      if (frame) replay_pool_->end_in_flight(*frame);
    }
  }

  std::size_t record(const std::byte* bytes, std::size_t size,
                     const std::function<std::uint8_t*(std::size_t)>& reserve) override {
    if (size != sizeof(Descriptor)) return 0;
    Descriptor descriptor;
    std::memcpy(&descriptor, bytes, sizeof descriptor);
    PoolMapping* pool = resolve(descriptor.block.pool_id);
    if (pool == nullptr || !T::valid_descriptor(descriptor, pool->block_size())) return 0;
    const std::size_t data = static_cast<std::size_t>(descriptor.data_size);
    // Reserved before the block is held: growing the chunk may allocate, and the reference
    // should last no longer than the copy itself.
    std::uint8_t* out = reserve(sizeof(Descriptor) + data);
    if (!pool->acquire(descriptor.block)) return 0;
    std::memcpy(out + sizeof(Descriptor), pool->block_data(descriptor.block.index), data);
    pool->release(descriptor.block.index);
    // The block named a use of a pool that ends with the run: a replay names its own, and two
    // recordings of the same frames compare equal.
    descriptor.block = msg::PoolBlock{};
    std::memcpy(out, &descriptor, sizeof descriptor);
    return sizeof(Descriptor) + data;
  }

  std::span<const std::byte> replay(std::span<const std::uint8_t> recorded) override {
    if (recorded.size() < sizeof(Descriptor)) return {};
    Descriptor descriptor;
    std::memcpy(&descriptor, recorded.data(), sizeof descriptor);
    if (!replay_pool_) {
      TensorPoolOptions options;
      options.namespace_name = namespace_;
      replay_pool_ = TensorPool::open("default", options).mapping();
    }
    const std::size_t data = recorded.size() - sizeof(Descriptor);
    if (descriptor.data_size != data ||
        !T::valid_descriptor(descriptor, std::max<std::size_t>(data, 1))) {
      return {};
    }
    const msg::PoolBlock block = replay_pool_->allocate(data);
    std::memcpy(replay_pool_->block_data(block.index), recorded.data() + sizeof(Descriptor), data);
    // As Topic<T>::send: the frame holds its block while in flight, the allocation's reference
    // (an Image handle's) goes.
    std::optional<msg::PoolBlock>& slot = in_flight_[next_];
    next_ = next_ + 1 == in_flight_.size() ? 0 : next_ + 1;
    if (slot) replay_pool_->end_in_flight(*slot);
    replay_pool_->begin_in_flight(block);
    replay_pool_->release(block.index);
    slot = block;
    descriptor.block = block;
    std::memcpy(descriptor_bytes_, &descriptor, sizeof descriptor);
    return {descriptor_bytes_, sizeof descriptor};
  }

 private:
  /// The pool of a descriptor: the last one seen, else looked up (once per pool, as a receiving
  /// Topic<T> does).
  PoolMapping* resolve(std::uint64_t pool_id) {
    if (record_pool_ && record_pool_->id() == pool_id) return record_pool_.get();
    if (pool_id == unknown_pool_) return nullptr;
    try {
      if (std::shared_ptr<PoolMapping> found = find_pool(pool_id, namespace_)) {
        record_pool_ = std::move(found);
        return record_pool_.get();
      }
    } catch (...) {
      // The pool folder cannot be read: no pool of it can be this one.
    }
    unknown_pool_ = pool_id;
    return nullptr;
  }

  std::string namespace_;
  std::shared_ptr<PoolMapping> record_pool_;
  std::uint64_t unknown_pool_ = 0;
  std::shared_ptr<PoolMapping> replay_pool_;
  std::vector<std::optional<msg::PoolBlock>> in_flight_;
  std::size_t next_ = 0;
  alignas(Descriptor) std::byte descriptor_bytes_[sizeof(Descriptor)]{};
};

template <class T>
bool is_type(std::string_view name, std::uint64_t fingerprint) {
  return name == TypeInfo<T>::name && fingerprint == TypeInfo<T>::fingerprint;
}

std::unique_ptr<PoolFrames> make_frames(std::string_view type_name, std::uint64_t fingerprint,
                                        const std::string& namespace_name, std::size_t keep) {
  if (is_type<Image>(type_name, fingerprint)) {
    return std::make_unique<TypedPoolFrames<Image>>(namespace_name, keep);
  }
  if (is_type<DepthImage>(type_name, fingerprint)) {
    return std::make_unique<TypedPoolFrames<DepthImage>>(namespace_name, keep);
  }
  if (is_type<PointCloud>(type_name, fingerprint)) {
    return std::make_unique<TypedPoolFrames<PointCloud>>(namespace_name, keep);
  }
  if (is_type<Tensor>(type_name, fingerprint)) {
    return std::make_unique<TypedPoolFrames<Tensor>>(namespace_name, keep);
  }
  return nullptr;
}

}  // namespace
}  // namespace horus::detail

namespace horus {

void enable_pool_frames() noexcept {
  detail::pool_frames_factory().store(&detail::make_frames, std::memory_order_release);
}

}  // namespace horus
