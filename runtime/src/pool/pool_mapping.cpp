// The reference protocol of a tensor pool (runtime/src/pool/README.md): allocation, acquisition,
// release, frames in flight, and giving back what dead processes held.
#include "horus/detail/pool_mapping.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <limits>
#include <mutex>
#include <string>
#include <thread>

#include "horus/detail/process.hpp"
#include "horus/error.hpp"
#include "horus/pool_frames.hpp"
#include "pool_layout.hpp"

namespace horus::detail {

namespace {

/// How long an acquirer waits for a release that is deciding whether to free its block (a few
/// loads of another process) before it yields, and before it gives up.
constexpr int kSpinsBeforeYield = 1000;
constexpr int kSpinsBeforeGivingUp = 100000;

// What orders a sender's writes to a block before a receiver's reads is the topic's ring (its
// release commit, the receiver's acquire). ThreadSanitizer cannot see that edge between two
// handles of one process: each maps the ring at an address of its own, and it tracks atomics by
// address. Under it (only), sends and receptions also meet on one word of the pool's single
// mapping, so that it sees the order the ring really gives; other builds touch nothing more.
inline void sanitizer_sent(BlockState& block) noexcept {
#if defined(__SANITIZE_THREAD__)
  block.sends.fetch_add(1, std::memory_order_release);
#else
  (void)block;
#endif
}
inline void sanitizer_received(BlockState& block) noexcept {
#if defined(__SANITIZE_THREAD__)
  (void)block.sends.load(std::memory_order_acquire);
#else
  (void)block;
#endif
}

inline void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

}  // namespace

PoolMapping::PoolMapping(FileDescriptor file, std::string path, std::string name,
                         const TensorPoolOptions& options)
    : name_(std::move(name)),
      path_(std::move(path)),
      file_(std::move(file)),
      policy_(options.on_exhaustion) {
  const MappedPool mapped = map_pool_file(file_.get(), path_, options);
  base_ = mapped.base;
  mapped_size_ = mapped.size;
  header_ = static_cast<PoolHeader*>(base_);
  id_ = header_->pool_id;
  block_size_ = static_cast<std::size_t>(mapped.geometry.block_size);
  block_count_ = static_cast<std::size_t>(mapped.geometry.block_count);
  geometry_ = mapped.geometry;
  data_ = static_cast<std::byte*>(base_) + geometry_.data_offset;
  sent_at_ = std::make_unique<std::atomic<std::uint64_t>[]>(block_count_);
}

PoolMapping::~PoolMapping() {
  if (registered_pid_.load(std::memory_order_relaxed) == this_pid()) {
    const std::size_t row = row_.load(std::memory_order_relaxed);
    // Every handle of this process is gone; anything left is given back, then the row.
    give_back(row);
    process(row).identity.store(0, std::memory_order_release);
  }
  ::munmap(base_, mapped_size_);
}

PoolProcess& PoolMapping::process(std::size_t row) const noexcept {
  return *reinterpret_cast<PoolProcess*>(static_cast<std::byte*>(base_) +
                                         geometry_.processes_offset + row * sizeof(PoolProcess));
}

BlockState& PoolMapping::state(std::uint32_t index) const noexcept {
  return *reinterpret_cast<BlockState*>(static_cast<std::byte*>(base_) + geometry_.states_offset +
                                        static_cast<std::size_t>(index) * sizeof(BlockState));
}

PoolHold& PoolMapping::hold(std::size_t row, std::uint32_t index) const noexcept {
  return *reinterpret_cast<PoolHold*>(static_cast<std::byte*>(base_) + geometry_.holds_offset +
                                      row * geometry_.row_stride +
                                      static_cast<std::size_t>(index) * sizeof(PoolHold));
}

bool PoolMapping::contains(const void* address) const noexcept {
  const auto* byte = static_cast<const std::byte*>(address);
  return byte >= data_ && byte < data_ + block_size_ * block_count_;
}

std::size_t PoolMapping::process_row() noexcept {
  if (registered_pid_.load(std::memory_order_acquire) == this_pid()) {
    return row_.load(std::memory_order_relaxed);
  }
  return register_process();
}

std::size_t PoolMapping::register_process() noexcept {
  const std::lock_guard<std::mutex> guard(register_mutex_);
  if (registered_pid_.load(std::memory_order_acquire) == this_pid()) {
    return row_.load(std::memory_order_relaxed);
  }
  const std::uint64_t me = this_process_identity();
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t row = 0; row < kMaxPoolProcesses; ++row) {
      std::uint64_t current = process(row).identity.load(std::memory_order_acquire);
      const bool free = pass == 0
                            ? current == 0
                            : current != 0 && current != kReclaimingRow && !identity_alive(current);
      if (free &&
          process(row).identity.compare_exchange_strong(current, me, std::memory_order_acq_rel)) {
        // A dead process's row: what it held goes back before this process counts in it.
        give_back(row);
        std::uint64_t used = header_->rows_used.load(std::memory_order_acquire);
        while (used < row + 1 && !header_->rows_used.compare_exchange_weak(
                                     used, row + 1, std::memory_order_acq_rel)) {
        }
        row_.store(row, std::memory_order_relaxed);
        registered_pid_.store(this_pid(), std::memory_order_release);
        return row;
      }
    }
  }
  return kNoRow;
}

std::optional<msg::PoolBlock> PoolMapping::try_allocate(std::size_t size) noexcept {
  if (size > block_size_) {
    return std::nullopt;
  }
  const std::size_t row = process_row();
  if (row == kNoRow) {
    return std::nullopt;
  }
  // Each pass that finds no free block first frees the blocks nobody holds any more, then takes
  // back what dead processes held (a syscall per process: only when exhausted), then applies the
  // policy; a pass after that which still finds nothing fails.
  bool reclaimed = false;
  for (std::size_t pass = 0; pass <= block_count_ + 1; ++pass) {
    const std::uint64_t start = header_->next_block.fetch_add(1, std::memory_order_relaxed);
    for (std::size_t i = 0; i < block_count_; ++i) {
      const auto index = static_cast<std::uint32_t>((start + i) % block_count_);
      BlockState& block = state(index);
      std::uint64_t current = block.word.load(std::memory_order_acquire);
      if (block_status(current) != kBlockFree) {
        continue;
      }
      // Counted before the block is taken: from the moment it is allocated it is held.
      PoolHold& mine = hold(row, index);
      mine.count.fetch_add(1, std::memory_order_seq_cst);
      std::uint32_t generation = block_generation(current) + 1;
      if (generation == 0) {
        generation = 1;
      }
      if (block.word.compare_exchange_strong(current, block_word(generation, kBlockAllocated, 0),
                                             std::memory_order_seq_cst)) {
        header_->allocations.fetch_add(1, std::memory_order_relaxed);
        return msg::PoolBlock{id_, index, generation};
      }
      drop_reference(row, index, 1);
    }
    if (sweep_unheld() > 0) {
      continue;
    }
    if (!reclaimed) {
      reclaimed = true;
      if (reclaim_dead() > 0) {
        continue;
      }
    }
    if (policy() != PoolExhaustion::DropOldest || !drop_oldest_in_flight()) {
      break;
    }
  }
  header_->exhausted.fetch_add(1, std::memory_order_relaxed);
  return std::nullopt;
}

msg::PoolBlock PoolMapping::allocate(std::size_t size) {
  if (size > block_size_) {
    throw Error("tensor pool " + path_ + ": " + std::to_string(size) +
                " bytes do not fit in a block of " + std::to_string(block_size_) +
                " (open a pool with a larger TensorPoolOptions::block_size)");
  }
  if (std::optional<msg::PoolBlock> block = try_allocate(size)) {
    return *block;
  }
  if (process_row() == kNoRow) {
    throw Error("tensor pool " + path_ + ": more than " + std::to_string(kMaxPoolProcesses) +
                " live processes use it");
  }
  throw Error("tensor pool " + path_ + " is exhausted: all " + std::to_string(block_count_) +
              " blocks are held" +
              (policy() == PoolExhaustion::DropOldest
                   ? " by live handles (no frame in flight left to drop)"
                   : " (policy Fail; DropOldest would give up unread frames in flight)") +
              "; release images, or open the pool with more blocks");
}

bool PoolMapping::acquire(const msg::PoolBlock& block) noexcept {
  const std::size_t row =
      block.pool_id == id_ && block.index < block_count_ && block.generation != 0 ? process_row()
                                                                                  : kNoRow;
  if (row == kNoRow) {
    header_->refused.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  hold(row, block.index).count.fetch_add(1, std::memory_order_seq_cst);
  // The hold is visible before the state is read (both sequentially consistent), and a freer
  // marks the block before it reads the holds: one of the two sees the other.
  for (int spin = 0; spin < kSpinsBeforeGivingUp; ++spin) {
    const std::uint64_t current = state(block.index).word.load(std::memory_order_seq_cst);
    if (block_generation(current) != block.generation) {
      break;
    }
    if (block_status(current) == kBlockAllocated) {
      sanitizer_received(state(block.index));
      return true;
    }
    if (block_status(current) != kBlockFreeing) {
      break;
    }
    if (spin >= kSpinsBeforeYield) {
      std::this_thread::yield();
    } else {
      cpu_relax();
    }
  }
  drop_reference(row, block.index, 1);
  header_->refused.fetch_add(1, std::memory_order_relaxed);
  return false;
}

void PoolMapping::add_reference(std::uint32_t index) noexcept {
  const std::size_t row = process_row();
  if (row != kNoRow) {
    hold(row, index).count.fetch_add(1, std::memory_order_relaxed);
  }
}

void PoolMapping::release(std::uint32_t index) noexcept {
  const std::size_t row = process_row();
  if (row != kNoRow) {
    drop_reference(row, index, 1);
  }
}

void PoolMapping::drop_reference(std::size_t row, std::uint32_t index,
                                 std::uint32_t count) noexcept {
  std::atomic<std::uint32_t>& held = hold(row, index).count;
  std::uint32_t current = held.load(std::memory_order_relaxed);
  std::uint32_t left = 0;
  do {
    // Never below zero: a forked child dropping handles its parent's row counted has none here.
    if (current == 0) {
      return;
    }
    left = current - std::min(current, count);
  } while (!held.compare_exchange_weak(current, left, std::memory_order_seq_cst));
  // A block nobody holds any more is not freed here but by the next allocation that finds no
  // free block (sweep_unheld): deciding that nobody holds it reads every process's row, lines
  // the sender writes on each send, and a receiver doing that per frame doubled a frame's
  // latency (bench/pool/RESULTS.md). Until then the block keeps its generation and its bytes,
  // so a late descriptor of it still reads the frame it names.
}

std::size_t PoolMapping::sweep_unheld() noexcept {
  std::size_t freed = 0;
  for (std::uint32_t index = 0; index < block_count_; ++index) {
    if (block_status(state(index).word.load(std::memory_order_acquire)) == kBlockAllocated &&
        !anybody_holds(index)) {
      try_free(index);
      freed += block_status(state(index).word.load(std::memory_order_acquire)) == kBlockFree;
    }
  }
  return freed;
}

bool PoolMapping::anybody_holds(std::uint32_t index) const noexcept {
  const std::uint64_t rows = std::min<std::uint64_t>(
      header_->rows_used.load(std::memory_order_seq_cst), kMaxPoolProcesses);
  for (std::size_t row = 0; row < rows; ++row) {
    if (hold(row, index).count.load(std::memory_order_seq_cst) != 0) {
      return true;
    }
  }
  return false;
}

void PoolMapping::try_free(std::uint32_t index) noexcept {
  std::atomic<std::uint64_t>& word = state(index).word;
  const auto freer = static_cast<std::uint32_t>(row_.load(std::memory_order_relaxed));
  for (;;) {
    std::uint64_t current = word.load(std::memory_order_seq_cst);
    if (block_status(current) != kBlockAllocated) {
      return;
    }
    const std::uint32_t generation = block_generation(current);
    if (!word.compare_exchange_strong(current, block_word(generation, kBlockFreeing, freer),
                                      std::memory_order_seq_cst)) {
      continue;
    }
    if (!anybody_holds(index)) {
      word.store(block_word(generation, kBlockFree, 0), std::memory_order_seq_cst);
      return;
    }
    word.store(current, std::memory_order_seq_cst);
    // A holder that let go while the block was marked could not free it (the mark made its
    // try_free return): look again after un-marking, so the last release is never lost.
    if (anybody_holds(index)) {
      return;
    }
  }
}

void PoolMapping::begin_in_flight(const msg::PoolBlock& block) noexcept {
  const std::size_t row = process_row();
  if (row == kNoRow || block.index >= block_count_) {
    return;
  }
  sanitizer_sent(state(block.index));
  PoolHold& mine = hold(row, block.index);
  mine.count.fetch_add(1, std::memory_order_relaxed);
  std::uint64_t current = mine.in_flight.load(std::memory_order_relaxed);
  std::uint64_t next = 0;
  do {
    next = in_flight_generation(current) == block.generation ? current + 1
                                                             : in_flight_word(block.generation, 1);
  } while (!mine.in_flight.compare_exchange_weak(current, next, std::memory_order_acq_rel));
  // Only an order for DropOldest: a plain increment (threads racing may share a value).
  const std::uint64_t now = send_clock_.load(std::memory_order_relaxed) + 1;
  send_clock_.store(now, std::memory_order_relaxed);
  sent_at_[block.index].store(now, std::memory_order_relaxed);
}

void PoolMapping::end_in_flight(const msg::PoolBlock& block) noexcept {
  const std::size_t row = process_row();
  if (row == kNoRow || block.index >= block_count_) {
    return;
  }
  std::atomic<std::uint64_t>& in_flight = hold(row, block.index).in_flight;
  std::uint64_t current = in_flight.load(std::memory_order_relaxed);
  do {
    // Dropped by the policy already (or the block was reallocated since): nothing to give.
    if (in_flight_generation(current) != block.generation || in_flight_count(current) == 0) {
      return;
    }
  } while (!in_flight.compare_exchange_weak(current, current - 1, std::memory_order_acq_rel));
  drop_reference(row, block.index, 1);
}

bool PoolMapping::drop_oldest_in_flight() noexcept {
  const std::size_t row = process_row();
  if (row == kNoRow) {
    return false;
  }
  for (;;) {
    std::uint32_t oldest = 0;
    std::uint64_t oldest_at = std::numeric_limits<std::uint64_t>::max();
    for (std::uint32_t index = 0; index < block_count_; ++index) {
      if (in_flight_count(hold(row, index).in_flight.load(std::memory_order_relaxed)) != 0 &&
          sent_at_[index].load(std::memory_order_relaxed) < oldest_at) {
        oldest = index;
        oldest_at = sent_at_[index].load(std::memory_order_relaxed);
      }
    }
    if (oldest_at == std::numeric_limits<std::uint64_t>::max()) {
      return false;
    }
    std::atomic<std::uint64_t>& in_flight = hold(row, oldest).in_flight;
    std::uint64_t current = in_flight.load(std::memory_order_relaxed);
    const std::uint32_t count = in_flight_count(current);
    if (count != 0 &&
        in_flight.compare_exchange_strong(current, in_flight_word(in_flight_generation(current), 0),
                                          std::memory_order_acq_rel)) {
      header_->dropped.fetch_add(count, std::memory_order_relaxed);
      drop_reference(row, oldest, count);
      return true;
    }
  }
}

void PoolMapping::give_back(std::size_t row) noexcept {
  for (std::uint32_t index = 0; index < block_count_; ++index) {
    PoolHold& held = hold(row, index);
    held.in_flight.store(0, std::memory_order_relaxed);
    std::atomic<std::uint64_t>& word = state(index).word;
    std::uint64_t current = word.load(std::memory_order_seq_cst);
    // Died between marking a block and deciding: un-mark it; the next sweep decides again.
    if (block_status(current) == kBlockFreeing && block_freer(current) == row) {
      word.compare_exchange_strong(current,
                                   block_word(block_generation(current), kBlockAllocated, 0),
                                   std::memory_order_seq_cst);
    }
    held.count.store(0, std::memory_order_seq_cst);
  }
}

std::size_t PoolMapping::reclaim_dead() noexcept {
  if (process_row() == kNoRow) {
    return 0;
  }
  std::size_t reclaimed = 0;
  const std::uint64_t me = this_process_identity();
  const std::uint64_t rows = std::min<std::uint64_t>(
      header_->rows_used.load(std::memory_order_acquire), kMaxPoolProcesses);
  for (std::size_t row = 0; row < rows; ++row) {
    std::uint64_t current = process(row).identity.load(std::memory_order_acquire);
    if (current == 0 || current == kReclaimingRow || current == me || identity_alive(current)) {
      continue;
    }
    if (process(row).identity.compare_exchange_strong(current, kReclaimingRow,
                                                      std::memory_order_acq_rel)) {
      give_back(row);
      process(row).identity.store(0, std::memory_order_release);
      header_->reclaimed.fetch_add(1, std::memory_order_relaxed);
      ++reclaimed;
    }
  }
  return reclaimed;
}

TensorPoolStats PoolMapping::stats() const noexcept {
  TensorPoolStats stats;
  stats.block_size = block_size_;
  stats.block_count = block_count_;
  for (std::uint32_t index = 0; index < block_count_; ++index) {
    if (block_status(state(index).word.load(std::memory_order_acquire)) != kBlockFree &&
        anybody_holds(index)) {
      ++stats.blocks_in_use;
    }
  }
  stats.allocations = header_->allocations.load(std::memory_order_relaxed);
  stats.exhausted = header_->exhausted.load(std::memory_order_relaxed);
  stats.dropped = header_->dropped.load(std::memory_order_relaxed);
  stats.refused = header_->refused.load(std::memory_order_relaxed);
  stats.reclaimed = header_->reclaimed.load(std::memory_order_relaxed);
  return stats;
}

std::uint64_t PoolMapping::references(const msg::PoolBlock& block) const noexcept {
  if (block.pool_id != id_ || block.index >= block_count_) {
    return 0;
  }
  const std::uint64_t current = state(block.index).word.load(std::memory_order_acquire);
  if (block_status(current) == kBlockFree || block_generation(current) != block.generation) {
    return 0;
  }
  std::uint64_t total = 0;
  const std::uint64_t rows = std::min<std::uint64_t>(
      header_->rows_used.load(std::memory_order_acquire), kMaxPoolProcesses);
  for (std::size_t row = 0; row < rows; ++row) {
    total += hold(row, block.index).count.load(std::memory_order_acquire);
  }
  return total;
}

namespace {
// A program that can hold a pool block records and replays pool-backed topics with their data
// (pool_frames.cpp): this file is linked whenever it can.
[[maybe_unused]] const bool pool_frames_enabled = (enable_pool_frames(), true);
}  // namespace

}  // namespace horus::detail
