// detail::McapWriter: writes an MCAP file (mcap_format.hpp) as HORUS records sessions: records in
// zstd chunks of about 1 MiB, each written whole and followed by its message indexes, then the
// data-end record, the summary and the footer (docs/recording.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
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

  /// Writes the open chunk if it holds anything; what a reader of a file cut now would see.
  void flush();
  /// Writes the open chunk, the data end, the summary and the footer, and closes the file.
  /// Idempotent; the destructor calls it (errors there are swallowed).
  void finish();

  /// Bytes written to the file so far.
  std::uint64_t file_size() const noexcept { return offset_; }
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

  void write_out(const std::uint8_t* data, std::size_t size);
  void write_chunk();

  std::filesystem::path path_;
  int fd_ = -1;
  std::size_t chunk_size_;
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;
  void* zstd_ = nullptr;  // ZSTD_CCtx

  mcap::Bytes chunk_;   // uncompressed records of the open chunk
  mcap::Bytes packed_;  // the chunk record and its message indexes as written
  std::size_t reserved_at_ = 0;
  std::uint64_t chunk_start_ = UINT64_MAX;
  std::uint64_t chunk_end_ = 0;
  std::size_t chunk_messages_ = 0;
  /// Per channel (index = id): (log_time, offset in the chunk) of the open chunk's messages.
  std::vector<std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;

  std::vector<std::vector<std::uint8_t>> schema_records_;  // copies for the summary
  std::vector<std::vector<std::uint8_t>> channel_records_;
  std::vector<std::uint64_t> channel_counts_;  // index = channel id
  std::vector<ChunkIndex> chunks_;
  std::vector<MetadataIndex> metadata_;
  std::uint64_t message_count_ = 0;
  std::uint64_t first_time_ = UINT64_MAX;
  std::uint64_t last_time_ = 0;
  bool finished_ = false;
};

}  // namespace horus::detail
