// horus::TensorPool: blocks of shared memory that Image, DepthImage, PointCloud and Tensor live in,
// shared between processes by reference count. A topic of those types sends only a descriptor
// naming the block (pool id, index, generation); the receiver maps the pool once and reads the
// data in place. runtime/src/pool/README.md describes the layout and the reference protocol.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include <horus/msg/pool_block.hpp>

namespace horus {

namespace detail {
class PoolMapping;
}

/// What an allocation does when every block is taken.
enum class PoolExhaustion : std::uint8_t {
  /// The allocation fails with a horus::Error saying so (counted in TensorPoolStats::exhausted).
  Fail,
  /// Frames this process sent that are still only in flight (in a topic's ring, taken by
  /// nobody yet) are given up, oldest first, until a block is free; a subscriber reaching such a
  /// frame later skips it (TensorPoolStats::dropped, refused). Fails like Fail when live handles
  /// hold every block.
  DropOldest,
};

/// How a pool is created. The geometry (block_size, block_count, mode) is the creator's: later
/// openers adopt the pool as it is. The exhaustion policy is each handle's own.
struct TensorPoolOptions {
  /// Bytes per block (rounded up to 4 KiB): the largest image, cloud or tensor the pool holds.
  /// The default fits a 1080p RGB or F32 depth image and a million XYZ points.
  std::size_t block_size = std::size_t{16} << 20;
  /// Blocks in the pool (at most 4096). /dev/shm gives pages only to blocks that were written.
  std::size_t block_count = 32;
  PoolExhaustion on_exhaustion = PoolExhaustion::Fail;
  /// Permissions of the pool file (0600: this user only). Group bits share it with a group.
  unsigned mode = 0600;
  /// Empty: HORUS_NAMESPACE, or "default".
  std::string namespace_name{};
};

/// Counters of a pool, shared by every process using it.
struct TensorPoolStats {
  std::size_t block_size = 0;
  std::size_t block_count = 0;
  /// Blocks somebody holds now.
  std::size_t blocks_in_use = 0;
  std::uint64_t allocations = 0;
  /// Allocations that failed because every block was taken.
  std::uint64_t exhausted = 0;
  /// In-flight frames given up under PoolExhaustion::DropOldest.
  std::uint64_t dropped = 0;
  /// Descriptors refused: their block was freed (or reused) or they name another pool.
  std::uint64_t refused = 0;
  /// Blocks taken back from processes that died holding them.
  std::uint64_t reclaimed = 0;
};

/// A handle on one pool (cheap to copy: every copy in a process shares one mapping).
class TensorPool {
 public:
  /// Opens or creates the pool `name` ([A-Za-z0-9_.-]) of the namespace, in
  /// <root>/@pool/<namespace>/<name> (root: HORUS_SHM_DIR or /dev/shm/horus-<euid>). Throws
  /// horus::Error for a bad name or options, a pool file another user could have planted or could
  /// write, a corrupt one, or no room in /dev/shm.
  static TensorPool open(std::string_view name = "default", const TensorPoolOptions& options = {});

  const std::string& name() const noexcept;
  /// The random identity every descriptor of this pool carries.
  std::uint64_t id() const noexcept;
  std::size_t block_size() const noexcept;
  std::size_t block_count() const noexcept;
  PoolExhaustion on_exhaustion() const noexcept;
  /// Changes this handle's policy (and that of every copy of it in this process).
  void set_on_exhaustion(PoolExhaustion policy) noexcept;
  TensorPoolStats stats() const noexcept;
  /// References every process holds on `block` now (handles plus frames in flight); 0 once it
  /// is free, or when `block` names another use of it or another pool.
  std::uint64_t references(const msg::PoolBlock& block) const noexcept;
  /// Whether `address` lies inside this process's mapping of the pool's blocks.
  bool contains(const void* address) const noexcept;
  /// Frees the blocks nobody holds any more and takes back what dead processes held (a slow
  /// path: a syscall per process using the pool). Allocations do both themselves when they find
  /// no free block; returns the blocks free afterwards that were not before.
  std::size_t reclaim() noexcept;

  /// The mapping behind the handle (for the pool-backed types).
  const std::shared_ptr<detail::PoolMapping>& mapping() const noexcept { return mapping_; }
  explicit TensorPool(std::shared_ptr<detail::PoolMapping> mapping) noexcept
      : mapping_(std::move(mapping)) {}

 private:
  std::shared_ptr<detail::PoolMapping> mapping_;
};

/// The pool that Image::make and the other make() functions use when given none: "default" of
/// the current namespace, opened (or created with the defaults) on first use.
TensorPool default_pool();

/// Removes every pool file of a namespace (empty: the current one). For tests and tools: handles
/// still open keep their mapping, but nobody new finds those pools.
void remove_pools(std::string_view namespace_name = {});

/// Removes the pool files of a namespace (empty: the current one) that no live process maps,
/// what `horus shm clean` does; returns how many. A pool in use is never touched.
std::size_t clean_pools(std::string_view namespace_name = {});

}  // namespace horus
