// The frame tree's shared-memory file: one per namespace, <root>/@frames/<namespace>, of a fixed
// size. README.md beside this file explains the layout and the read protocol.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "horus/frames.hpp"

namespace horus::detail::frames {

inline constexpr std::uint64_t kTreeMagic = 0x4d52465355524f48ULL;  // "HORUSFRM"
inline constexpr std::uint32_t kTreeVersion = 1;
inline constexpr std::size_t kHeaderSize = 4096;
inline constexpr std::size_t kNameBytes = kMaxFrameName + 1;

/// Words of one history entry: stamp, parent index + 1, translation (3), rotation (4).
inline constexpr std::size_t kEntryWords = 9;

/// One transform of a frame's history, under a sequence lock: `seq` is 2t+1 while ticket t is
/// being written and 2t+2 once it is complete, so a reader knows both that the words are whole
/// and that they are ticket t's (not a later lap's).
struct HistoryEntry {
  std::atomic<std::uint64_t> seq;
  std::atomic<std::uint64_t> words[kEntryWords];
};
static_assert(sizeof(HistoryEntry) == 80);

struct FrameSlot {
  /// Written once before the slot is published (TreeHeader::frame_count), never changed after.
  char name[kNameBytes];
  std::uint64_t name_hash;
  /// The identity (detail/process.hpp) of the process that sets this frame; 0: none (a root).
  std::atomic<std::uint64_t> authority;
  /// The parent's index + 1; 0 for a root. Stored after the entries it applies to.
  std::atomic<std::uint32_t> parent;
  std::atomic<std::uint32_t> is_static;
  /// The first ticket written under the current parent and kind: older ones do not apply.
  std::atomic<std::uint64_t> first_ticket;
  /// Tickets completed; ticket t lives in entries[t % kFrameHistoryEntries].
  std::atomic<std::uint64_t> write_count;
  char reserved[64 - 40];
  HistoryEntry entries[kFrameHistoryEntries];
};
static_assert(sizeof(FrameSlot) % 64 == 0);

struct TreeHeader {
  std::uint64_t magic;
  std::uint32_t version;
  std::uint32_t header_size;
  std::uint64_t max_frames;
  std::uint64_t history_entries;
  std::uint64_t frame_size;
  std::uint64_t total_size;
  /// How long dynamic transforms stay answerable (the creator's FrameTreeOptions::history).
  std::int64_t history_ns;
  /// Frames published; slots [0, frame_count) are in use. Only grows.
  alignas(64) std::atomic<std::uint32_t> frame_count;
  /// The change counter and futex word: bumped after every write.
  alignas(64) std::atomic<std::uint32_t> changes;
  /// Threads sleeping on `changes`: a writer makes the wake system call only when there are any.
  std::atomic<std::uint32_t> waiters;
};
static_assert(sizeof(TreeHeader) <= kHeaderSize);

inline constexpr std::size_t kTotalSize = kHeaderSize + kMaxFrames * sizeof(FrameSlot);

}  // namespace horus::detail::frames
