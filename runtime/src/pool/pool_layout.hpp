// The shared layout of a tensor pool file (runtime/src/pool/README.md):
//
//   [0, 4096)                 PoolHeader: identity, geometry, shared counters
//   [processes_offset, ..)    kMaxPoolProcesses PoolProcess rows: who counts in each holds row
//   [states_offset, ..)       block_count BlockStates: generation and status of each block
//   [holds_offset, ..)        kMaxPoolProcesses rows of block_count PoolHolds (row_stride apart)
//   [data_offset, total_size) block_count blocks of block_size bytes, 4 KiB aligned
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

#include "horus/detail/pool_mapping.hpp"
#include "horus/tensor_pool.hpp"

namespace horus::detail {

inline constexpr std::uint64_t kPoolMagic = 0x4c4f4f5053555248ULL;  // "HRUSPOOL"
inline constexpr std::uint32_t kPoolVersion = 1;
inline constexpr std::size_t kPoolHeaderSize = 4096;
inline constexpr std::size_t kMaxPoolProcesses = 64;
inline constexpr std::size_t kMaxPoolBlocks = 4096;
inline constexpr std::uint64_t kPoolPage = 4096;
/// Blocks of at most 1 GiB, pools of at most 64 GiB: anything larger is a mistake.
inline constexpr std::uint64_t kMaxPoolBlockSize = std::uint64_t{1} << 30;
inline constexpr std::uint64_t kMaxPoolSize = std::uint64_t{64} << 30;
inline constexpr std::size_t kNoRow = static_cast<std::size_t>(-1);
/// PoolProcess::identity of a dead process's row while somebody gives back what it held.
inline constexpr std::uint64_t kReclaimingRow = ~std::uint64_t{0};

struct PoolHeader {
  std::uint64_t magic;
  std::uint32_t version;
  std::uint32_t header_size;
  std::uint64_t pool_id;
  std::uint64_t block_size;
  std::uint64_t block_count;
  std::uint64_t max_processes;
  std::uint64_t processes_offset;
  std::uint64_t states_offset;
  std::uint64_t holds_offset;
  std::uint64_t row_stride;
  std::uint64_t data_offset;
  std::uint64_t total_size;
  /// 1 once the layout is complete (written under the set-up lock).
  std::atomic<std::uint32_t> ready;
  std::uint32_t reserved;
  /// Holds rows ever registered: the ones a freer scans.
  alignas(64) std::atomic<std::uint64_t> rows_used;
  /// Where the next allocation starts looking, so blocks are used in turn.
  alignas(64) std::atomic<std::uint64_t> next_block;
  alignas(64) std::atomic<std::uint64_t> allocations;
  std::atomic<std::uint64_t> exhausted;
  std::atomic<std::uint64_t> dropped;
  std::atomic<std::uint64_t> refused;
  std::atomic<std::uint64_t> reclaimed;
};
static_assert(sizeof(PoolHeader) <= kPoolHeaderSize);

struct PoolProcess {
  /// The identity (detail/process.hpp) of the process counting in this row; 0 when free.
  std::atomic<std::uint64_t> identity;
  std::uint64_t reserved[7];
};
static_assert(sizeof(PoolProcess) == 64);

/// Status of a block, in the low bits of its state word.
inline constexpr std::uint32_t kBlockFree = 0;
inline constexpr std::uint32_t kBlockAllocated = 1;
/// Its last reference in some row was dropped: the freer (whose row is in bits 8..15) is
/// checking every row before it frees the block.
inline constexpr std::uint32_t kBlockFreeing = 2;

struct BlockState {
  /// generation << 32 | freer row << 8 | status.
  std::atomic<std::uint64_t> word;
  /// Written and read only under ThreadSanitizer (see sanitizer_published in pool_mapping.cpp).
  std::atomic<std::uint64_t> sends;
  std::uint64_t reserved[6];
};
static_assert(sizeof(BlockState) == 64);

inline std::uint64_t block_word(std::uint32_t generation, std::uint32_t status,
                                std::uint32_t freer) noexcept {
  return std::uint64_t{generation} << 32 | std::uint64_t{(freer & 0xffU) << 8} | status;
}
inline std::uint32_t block_generation(std::uint64_t word) noexcept {
  return static_cast<std::uint32_t>(word >> 32);
}
inline std::uint32_t block_status(std::uint64_t word) noexcept {
  return static_cast<std::uint32_t>(word & 0xffU);
}
inline std::uint32_t block_freer(std::uint64_t word) noexcept {
  return static_cast<std::uint32_t>((word >> 8) & 0xffU);
}

/// One process's references on one block.
struct PoolHold {
  /// Handles plus frames in flight; written only by the process of the row (and by whoever
  /// gives back a dead one's row).
  std::atomic<std::uint32_t> count;
  std::uint32_t reserved;
  /// generation << 32 | frames in flight (also counted in `count`).
  std::atomic<std::uint64_t> in_flight;
};
static_assert(sizeof(PoolHold) == 16);

inline std::uint64_t in_flight_word(std::uint32_t generation, std::uint32_t count) noexcept {
  return std::uint64_t{generation} << 32 | count;
}
inline std::uint32_t in_flight_generation(std::uint64_t word) noexcept {
  return static_cast<std::uint32_t>(word >> 32);
}
inline std::uint32_t in_flight_count(std::uint64_t word) noexcept {
  return static_cast<std::uint32_t>(word);
}

struct MappedPool {
  void* base = nullptr;
  std::size_t size = 0;
  PoolGeometry geometry{};
};

/// Maps the pool file `file` (opened, checked and locked by the caller), laying it out for
/// `options` when it is new (or its creator died before finishing). Throws horus::Error.
MappedPool map_pool_file(int file, const std::string& path, const TensorPoolOptions& options);

}  // namespace horus::detail
