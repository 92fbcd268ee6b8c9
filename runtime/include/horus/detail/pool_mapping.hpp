// One process's mapping of a tensor pool, and the references it hands out. The shared layout and
// the reference protocol are in runtime/src/pool/README.md; what matters here:
//  - every reference (a BlockRef, or a frame in flight in a topic's ring) is counted in this
//    process's own row of the holds table, so a process that dies gives its references back when
//    somebody notices (the pid and start time of detail/process.hpp);
//  - a block is used under a generation, bumped at each allocation; a descriptor of an older
//    generation, or of another pool, is refused and never dereferenced;
//  - allocation, acquisition and release are a few atomic operations on shared memory: no
//    syscall, lock or heap allocation unless the pool is exhausted;
//  - a release only counts down its own row: the block is freed by the next allocation that
//    finds no free block (sweep_unheld), which keeps a receiver off the rows its sender writes.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <horus/msg/pool_block.hpp>

#include "horus/detail/shm_access.hpp"
#include "horus/tensor_pool.hpp"

namespace horus::detail {

struct PoolHeader;
struct PoolProcess;
struct BlockState;
struct PoolHold;

/// Where the tables of a mapped pool start, copied out of its validated header: the hot paths
/// never re-read a size another process could corrupt.
struct PoolGeometry {
  std::uint64_t block_size = 0;
  std::uint64_t block_count = 0;
  std::uint64_t processes_offset = 0;
  std::uint64_t states_offset = 0;
  std::uint64_t holds_offset = 0;
  std::uint64_t row_stride = 0;
  std::uint64_t data_offset = 0;
  std::uint64_t total_size = 0;
};

class PoolMapping : public std::enable_shared_from_this<PoolMapping> {
 public:
  /// Maps the pool file (already opened, checked and locked) `file` at `path`, creating its layout
  /// when it is new, and keeps the file open: its lock tells cleaners the pool is in use. Throws
  /// horus::Error.
  PoolMapping(FileDescriptor file, std::string path, std::string name,
              const TensorPoolOptions& options);
  PoolMapping(const PoolMapping&) = delete;
  PoolMapping& operator=(const PoolMapping&) = delete;
  ~PoolMapping();

  const std::string& name() const noexcept { return name_; }
  const std::string& path() const noexcept { return path_; }
  int file() const noexcept { return file_.get(); }
  std::uint64_t id() const noexcept { return id_; }
  std::size_t block_size() const noexcept { return block_size_; }
  std::size_t block_count() const noexcept { return block_count_; }
  PoolExhaustion policy() const noexcept { return policy_.load(std::memory_order_relaxed); }
  void set_policy(PoolExhaustion policy) noexcept {
    policy_.store(policy, std::memory_order_relaxed);
  }

  std::byte* block_data(std::uint32_t index) const noexcept {
    return data_ + static_cast<std::size_t>(index) * block_size_;
  }
  bool contains(const void* address) const noexcept;

  /// A fresh block of at least `size` bytes, held once by this process; nullopt (counted in
  /// exhausted) when every block is taken after the policy did what it could, or when `size`
  /// exceeds a block.
  std::optional<msg::PoolBlock> try_allocate(std::size_t size) noexcept;
  /// try_allocate, or a horus::Error saying why not.
  msg::PoolBlock allocate(std::size_t size);
  /// Takes one reference on `block` if it is a current block of this pool; false (counted as
  /// refused) otherwise, and nothing is held.
  bool acquire(const msg::PoolBlock& block) noexcept;
  /// Takes one more reference on a block this process already holds (copying a handle).
  void add_reference(std::uint32_t index) noexcept;
  /// Gives back one reference (the block is freed later, by an allocation that needs it).
  void release(std::uint32_t index) noexcept;

  /// A frame of a block this process holds enters a topic's ring: one more reference, which
  /// end_in_flight() or the DropOldest policy gives back.
  void begin_in_flight(const msg::PoolBlock& block) noexcept;
  /// The frame left the ring (overwritten, or its topic handle closed): gives its reference back
  /// unless the policy already dropped it.
  void end_in_flight(const msg::PoolBlock& block) noexcept;

  TensorPoolStats stats() const noexcept;
  std::uint64_t references(const msg::PoolBlock& block) const noexcept;
  /// Takes back what dead processes held; returns how many processes' rows it emptied.
  std::size_t reclaim_dead() noexcept;
  /// Frees the blocks nobody holds any more (see drop_reference); returns how many.
  std::size_t sweep_unheld() noexcept;

 private:
  PoolProcess& process(std::size_t row) const noexcept;
  BlockState& state(std::uint32_t index) const noexcept;
  PoolHold& hold(std::size_t row, std::uint32_t index) const noexcept;
  /// This process's row in the holds table, registering it (or re-registering a forked child).
  std::size_t process_row() noexcept;
  std::size_t register_process() noexcept;
  void drop_reference(std::size_t row, std::uint32_t index, std::uint32_t count) noexcept;
  void try_free(std::uint32_t index) noexcept;
  bool anybody_holds(std::uint32_t index) const noexcept;
  bool drop_oldest_in_flight() noexcept;
  void give_back(std::size_t row) noexcept;

  std::string name_;
  std::string path_;
  /// Held with a shared flock for the mapping's life (see open_mapping in tensor_pool.cpp).
  FileDescriptor file_;
  void* base_ = nullptr;
  std::size_t mapped_size_ = 0;
  PoolHeader* header_ = nullptr;
  std::byte* data_ = nullptr;
  std::uint64_t id_ = 0;
  std::size_t block_size_ = 0;
  std::size_t block_count_ = 0;
  PoolGeometry geometry_{};
  std::atomic<PoolExhaustion> policy_;
  /// This process's row (meaningful while registered_pid_ is this process's pid).
  std::atomic<std::size_t> row_{0};
  std::atomic<std::uint32_t> registered_pid_{0};
  /// Two threads using the pool first at once must not take two rows (slow path, once).
  std::mutex register_mutex_;
  /// When this process last sent each block, for DropOldest (in this process's memory: only it
  /// drops its own frames).
  std::unique_ptr<std::atomic<std::uint64_t>[]> sent_at_;
  std::atomic<std::uint64_t> send_clock_{0};
};

/// One reference on a pool block: copying takes another, destruction gives it back.
class BlockRef {
 public:
  BlockRef() noexcept = default;
  /// Adopts a reference already taken on `block` (by allocate or acquire).
  BlockRef(std::shared_ptr<PoolMapping> pool, const msg::PoolBlock& block) noexcept
      : pool_(std::move(pool)), block_(block) {}
  BlockRef(const BlockRef& other) noexcept : pool_(other.pool_), block_(other.block_) {
    if (pool_) {
      pool_->add_reference(block_.index);
    }
  }
  BlockRef(BlockRef&& other) noexcept : pool_(std::move(other.pool_)), block_(other.block_) {}
  BlockRef& operator=(BlockRef other) noexcept {
    std::swap(pool_, other.pool_);
    std::swap(block_, other.block_);
    return *this;
  }
  ~BlockRef() {
    if (pool_) {
      pool_->release(block_.index);
    }
  }

  explicit operator bool() const noexcept { return static_cast<bool>(pool_); }
  const msg::PoolBlock& block() const noexcept { return block_; }
  PoolMapping* pool() const noexcept { return pool_.get(); }
  const std::shared_ptr<PoolMapping>& shared_pool() const noexcept { return pool_; }
  std::byte* data() const noexcept { return pool_ ? pool_->block_data(block_.index) : nullptr; }

 private:
  std::shared_ptr<PoolMapping> pool_;
  msg::PoolBlock block_{};
};

/// The pool with identity `id` in the namespace (empty: the current one), from the pools this
/// process has open or, failing that, by opening the namespace's pool files; nullptr when no pool
/// of the namespace has it. A slow path (the first time a receiver meets a pool).
std::shared_ptr<PoolMapping> find_pool(std::uint64_t id, const std::string& namespace_name);

}  // namespace horus::detail
