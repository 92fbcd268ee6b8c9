// detail::McapWriter: writes an MCAP file (mcap_format.hpp) as HORUS records sessions: records in
// zstd chunks of about 1 MiB, each written whole and followed by its message indexes, then the
// data-end record, the summary and the footer (docs/recording.md). The caller fills chunks; a
// thread of the writer's own compresses and writes them, so a disk that stalls a write() does not
// stall whoever takes messages off the rings (up to kMaxQueuedBytes waiting).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <exception>
#include <filesystem>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "mcap_format.hpp"

namespace horus::detail {

using McapMap = std::vector<std::pair<std::string, std::string>>;

class McapWriter {
 public:
  /// Creates `path` (refusing to replace an existing file) and writes the magic and the header;
  /// throws horus::Error naming the path and the reason.
  explicit McapWriter(const std::filesystem::path& path,
                      std::size_t chunk_size = std::size_t{1} << 20);
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Ids start at 1; each record goes into the current chunk.
  std::uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  std::uint16_t add_channel(std::string_view topic, std::uint16_t schema_id,
                            std::string_view message_encoding, const McapMap& metadata);

  /// Room for a message of up to `size` data bytes at the end of the current chunk, to be
  /// filled in place (no copy in between) and then kept with commit_message(); a later call
  /// (or add_message) before the commit overwrites it.
  std::uint8_t* reserve_message(std::size_t size);
  void commit_message(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                      std::uint64_t publish_time, std::size_t size);
  void add_message(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, std::span<const std::uint8_t> data);

  /// A Metadata record, written between chunks (the open chunk is written first).
  void add_metadata(std::string_view name, const McapMap& entries);

  /// Hands the open chunk, if it holds anything, to the writing thread.
  void flush();
  /// Writes the open chunk, the data end, the summary and the footer, and closes the file.
  /// Idempotent; the destructor calls it (errors there are swallowed).
  void finish();

  /// Bytes written to the file so far.
  std::uint64_t file_size() const noexcept { return offset_.load(std::memory_order_relaxed); }
  std::uint64_t message_count() const noexcept { return message_count_; }
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  struct ChunkIndex {
    std::uint64_t start_time, end_time, offset, length, index_length, compressed, uncompressed;
    std::vector<std::pair<std::uint16_t, std::uint64_t>> index_offsets;
  };
  struct MetadataIndex {
    std::uint64_t offset, length;
    std::string name;
  };

  /// A chunk's records or a metadata record, on its way to the writing thread.
  struct Job {
    mcap::Bytes records;
    bool chunk = true;
    std::uint64_t start_time = 0, end_time = 0;
    std::vector<std::pair<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>>>
        indexes;  // per channel: (log_time, offset in the chunk) of its messages
    std::string metadata_name;
  };
  /// Chunks waiting for the disk beyond this make the caller wait (and its rings overflow).
  static constexpr std::size_t kMaxQueuedBytes = std::size_t{256} << 20;

  void write_out(const std::uint8_t* data, std::size_t size);
  /// Hands `job` to the writing thread; rethrows what that thread failed with.
  void enqueue(Job job);
  void enqueue_chunk();
  void run_writer() noexcept;
  void write_chunk(Job& job);
  void write_metadata(Job& job);
  void stop_writer();

  std::filesystem::path path_;
  int fd_ = -1;
  std::size_t chunk_size_;
  void* zstd_ = nullptr;  // ZSTD_CCtx

  // The caller's side.
  mcap::Bytes chunk_;  // uncompressed records of the open chunk
  std::size_t reserved_at_ = 0;
  std::uint64_t chunk_start_ = UINT64_MAX;
  std::uint64_t chunk_end_ = 0;
  std::size_t chunk_messages_ = 0;
  /// Per channel (index = id): (log_time, offset in the chunk) of the open chunk's messages.
  std::vector<std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;

  // Between the two sides (mutex_).
  std::mutex mutex_;
  std::condition_variable work_;
  std::condition_variable space_;
  std::deque<Job> queue_;
  std::vector<mcap::Bytes> spare_buffers_;  // written chunks' buffers, for the next chunks
  std::size_t queued_bytes_ = 0;
  bool closing_ = false;
  std::exception_ptr error_;
  std::thread writer_;

  // The writing thread's side (the caller's again once it has joined).
  std::atomic<std::uint64_t> offset_{0};
  std::uint32_t data_crc_ = 0;
  mcap::Bytes packed_;  // the chunk record and its message indexes as written
  std::vector<ChunkIndex> chunks_;
  std::vector<MetadataIndex> metadata_;

  std::vector<std::vector<std::uint8_t>> schema_records_;  // copies for the summary
  std::vector<std::vector<std::uint8_t>> channel_records_;
  std::vector<std::uint64_t> channel_counts_;  // index = channel id
  std::uint64_t message_count_ = 0;
  std::uint64_t first_time_ = UINT64_MAX;
  std::uint64_t last_time_ = 0;
  bool finished_ = false;
};

}  // namespace horus::detail
