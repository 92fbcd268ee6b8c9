// The MCAP writer: see mcap_writer.hpp and docs/recording.md.
#include "mcap_writer.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"

namespace horus::detail {
namespace {

/// zstd's fastest regular level: a session must be written as fast as the robot produces it.
constexpr int kZstdLevel = 1;

std::vector<std::uint8_t> copy_record(const mcap::Bytes& from, std::size_t begin) {
  return {from.data() + begin, from.data() + from.size()};
}

/// A Map<string, string> field.
void put_map(mcap::Bytes& bytes, const McapMap& entries) {
  const std::size_t map = bytes.begin_block();
  for (const auto& [key, value] : entries) {
    bytes.string(key);
    bytes.string(value);
  }
  bytes.end_block(map);
}

}  // namespace

McapWriter::McapWriter(const std::filesystem::path& path, std::size_t chunk_size)
    : path_(path), chunk_size_(chunk_size) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw Error("cannot create recording " + path.string() + ": " + errno_text(errno));
  }
  zstd_ = ZSTD_createCCtx();
  if (zstd_ == nullptr) {
    ::close(fd_);
    throw Error("cannot create recording " + path.string() + ": out of memory for zstd");
  }
  mcap::Bytes start;
  start.raw(mcap::kMagic.data(), mcap::kMagic.size());
  const std::size_t header = start.begin_record(mcap::Op::Header);
  start.string("horus");
  start.string(std::string("horus ") + HORUS_VERSION_STRING);
  start.end_record(header);
  write_out(start.data(), start.size());
  writer_ = std::thread([this] { run_writer(); });
}

McapWriter::~McapWriter() {
  try {
    finish();
  } catch (...) {
    // A destructor cannot report it; finish() called explicitly does.
  }
  stop_writer();
  if (fd_ >= 0) ::close(fd_);
  ZSTD_freeCCtx(static_cast<ZSTD_CCtx*>(zstd_));
}

void McapWriter::write_out(const std::uint8_t* data, std::size_t size) {
  data_crc_ = mcap::crc32(data_crc_, data, size);
  while (size > 0) {
    const ssize_t wrote = ::write(fd_, data, size);
    if (wrote < 0) {
      if (errno == EINTR) continue;
      throw Error("cannot write recording " + path_.string() + ": " + errno_text(errno));
    }
    data += wrote;
    size -= static_cast<std::size_t>(wrote);
    offset_.store(offset_.load(std::memory_order_relaxed) + static_cast<std::uint64_t>(wrote),
                  std::memory_order_relaxed);
  }
}

std::uint16_t McapWriter::add_schema(std::string_view name, std::string_view encoding,
                                     std::string_view data) {
  const auto id = static_cast<std::uint16_t>(schema_records_.size() + 1);
  const std::size_t begin = chunk_.size();
  const std::size_t record = chunk_.begin_record(mcap::Op::Schema);
  chunk_.put(id);
  chunk_.string(name);
  chunk_.string(encoding);
  chunk_.string(data);
  chunk_.end_record(record);
  schema_records_.push_back(copy_record(chunk_, begin));
  return id;
}

std::uint16_t McapWriter::add_channel(std::string_view topic, std::uint16_t schema_id,
                                      std::string_view message_encoding, const McapMap& metadata) {
  const auto id = static_cast<std::uint16_t>(channel_records_.size() + 1);
  const std::size_t begin = chunk_.size();
  const std::size_t record = chunk_.begin_record(mcap::Op::Channel);
  chunk_.put(id);
  chunk_.put(schema_id);
  chunk_.string(topic);
  chunk_.string(message_encoding);
  put_map(chunk_, metadata);
  chunk_.end_record(record);
  channel_records_.push_back(copy_record(chunk_, begin));
  channel_counts_.resize(id + 1, 0);
  chunk_index_.resize(id + 1);
  return id;
}

std::uint8_t* McapWriter::reserve_message(std::size_t size) {
  reserved_at_ = chunk_.size();
  std::uint8_t* record = chunk_.grow(mcap::kRecordPrefix + mcap::kMessageFixed + size);
  chunk_.truncate(reserved_at_);  // the bytes stay allocated: commit_message takes them back
  return record + mcap::kRecordPrefix + mcap::kMessageFixed;
}

void McapWriter::commit_message(std::uint16_t channel, std::uint32_t sequence,
                                std::uint64_t log_time, std::uint64_t publish_time,
                                std::size_t size) {
  const std::size_t at = reserved_at_;
  const std::size_t total = mcap::kRecordPrefix + mcap::kMessageFixed + size;
  std::uint8_t* record = chunk_.grow(total);
  record[0] = static_cast<std::uint8_t>(mcap::Op::Message);
  const std::uint64_t length = total - mcap::kRecordPrefix;
  std::memcpy(record + 1, &length, 8);
  std::memcpy(record + 9, &channel, 2);
  std::memcpy(record + 11, &sequence, 4);
  std::memcpy(record + 15, &log_time, 8);
  std::memcpy(record + 23, &publish_time, 8);
  chunk_index_.at(channel).emplace_back(log_time, at);
  ++channel_counts_.at(channel);
  ++chunk_messages_;
  ++message_count_;
  chunk_start_ = std::min(chunk_start_, log_time);
  chunk_end_ = std::max(chunk_end_, log_time);
  first_time_ = std::min(first_time_, log_time);
  last_time_ = std::max(last_time_, log_time);
  if (chunk_.size() >= chunk_size_) enqueue_chunk();
}

void McapWriter::add_message(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                             std::uint64_t publish_time, std::span<const std::uint8_t> data) {
  std::uint8_t* at = reserve_message(data.size());
  if (!data.empty()) std::memcpy(at, data.data(), data.size());
  commit_message(channel, sequence, log_time, publish_time, data.size());
}

void McapWriter::enqueue(Job job) {
  std::unique_lock lock(mutex_);
  space_.wait(lock, [&] { return queued_bytes_ < kMaxQueuedBytes || error_ != nullptr; });
  if (error_) std::rethrow_exception(error_);
  queued_bytes_ += job.records.size();
  queue_.push_back(std::move(job));
  work_.notify_one();
}

void McapWriter::enqueue_chunk() {
  Job job;
  job.start_time = chunk_messages_ > 0 ? chunk_start_ : 0;
  job.end_time = chunk_end_;
  for (std::size_t channel = 1; channel < chunk_index_.size(); ++channel) {
    if (chunk_index_[channel].empty()) continue;
    job.indexes.emplace_back(static_cast<std::uint16_t>(channel), std::move(chunk_index_[channel]));
    chunk_index_[channel].clear();
  }
  job.records = std::move(chunk_);
  {
    std::lock_guard lock(mutex_);
    if (!spare_buffers_.empty()) {
      chunk_ = std::move(spare_buffers_.back());
      spare_buffers_.pop_back();
    }
  }
  chunk_.clear();
  chunk_messages_ = 0;
  chunk_start_ = UINT64_MAX;
  chunk_end_ = 0;
  enqueue(std::move(job));
}

void McapWriter::run_writer() noexcept {
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      work_.wait(lock, [&] { return !queue_.empty() || closing_; });
      if (queue_.empty()) return;
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    const std::size_t size = job.records.size();
    try {
      if (job.chunk) {
        write_chunk(job);
      } else {
        write_metadata(job);
      }
    } catch (...) {
      std::lock_guard lock(mutex_);
      error_ = std::current_exception();
      queue_.clear();
      queued_bytes_ = 0;
      space_.notify_all();
      return;
    }
    std::lock_guard lock(mutex_);
    queued_bytes_ -= size;
    if (job.chunk && spare_buffers_.size() < 2) spare_buffers_.push_back(std::move(job.records));
    space_.notify_all();
  }
}

void McapWriter::stop_writer() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
    work_.notify_one();
  }
  if (writer_.joinable()) writer_.join();
}

void McapWriter::write_chunk(Job& job) {
  const mcap::Bytes& records = job.records;
  const std::size_t bound = ZSTD_compressBound(records.size());
  const std::uint64_t offset = offset_.load(std::memory_order_relaxed);
  packed_.clear();
  const std::size_t record = packed_.begin_record(mcap::Op::Chunk);
  packed_.put(job.start_time);
  packed_.put(job.end_time);
  packed_.put(static_cast<std::uint64_t>(records.size()));
  packed_.put(mcap::crc32(0, records.data(), records.size()));
  packed_.string("zstd");
  const std::size_t length_at = packed_.size();
  packed_.put(std::uint64_t{0});
  std::uint8_t* out = packed_.grow(bound);
  const std::size_t compressed = ZSTD_compressCCtx(static_cast<ZSTD_CCtx*>(zstd_), out, bound,
                                                   records.data(), records.size(), kZstdLevel);
  if (ZSTD_isError(compressed) != 0) {
    throw Error("cannot compress a chunk of recording " + path_.string() + ": " +
                ZSTD_getErrorName(compressed));
  }
  packed_.truncate(length_at + 8 + compressed);
  packed_.patch64(length_at, compressed);
  packed_.end_record(record);

  ChunkIndex index{job.start_time, job.end_time,   offset, packed_.size(), 0,
                   compressed,     records.size(), {}};
  for (const auto& [channel, entries] : job.indexes) {
    index.index_offsets.emplace_back(channel, offset + packed_.size());
    const std::size_t message_index = packed_.begin_record(mcap::Op::MessageIndex);
    packed_.put(channel);
    const std::size_t array = packed_.begin_block();
    for (const auto& [time, at] : entries) {
      packed_.put(time);
      packed_.put(at);
    }
    packed_.end_block(array);
    packed_.end_record(message_index);
  }
  index.index_length = packed_.size() - index.length;
  // One write for the chunk and its indexes: a recorder killed mid-way leaves every earlier
  // chunk complete, and at most this one cut short.
  write_out(packed_.data(), packed_.size());
  chunks_.push_back(std::move(index));
}

void McapWriter::write_metadata(Job& job) {
  metadata_.push_back(MetadataIndex{offset_.load(std::memory_order_relaxed), job.records.size(),
                                    std::move(job.metadata_name)});
  write_out(job.records.data(), job.records.size());
}

void McapWriter::flush() {
  if (chunk_.size() > 0) enqueue_chunk();
}

void McapWriter::add_metadata(std::string_view name, const McapMap& entries) {
  flush();
  Job job;
  job.chunk = false;
  job.metadata_name = std::string(name);
  mcap::Bytes& bytes = job.records;
  const std::size_t record = bytes.begin_record(mcap::Op::Metadata);
  bytes.string(name);
  put_map(bytes, entries);
  bytes.end_record(record);
  enqueue(std::move(job));
}

void McapWriter::finish() {
  if (finished_ || fd_ < 0) return;
  finished_ = true;
  flush();
  stop_writer();
  {
    std::lock_guard lock(mutex_);
    if (error_) std::rethrow_exception(error_);
  }
  mcap::Bytes end;
  const std::size_t data_end = end.begin_record(mcap::Op::DataEnd);
  end.put(data_crc_);
  end.end_record(data_end);
  write_out(end.data(), end.size());

  // The summary: every group is one run of records, then a SummaryOffset per group.
  const std::uint64_t summary_start = offset_.load(std::memory_order_relaxed);
  mcap::Bytes summary;
  struct Group {
    mcap::Op op;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  const auto group = [&](mcap::Op op, auto&& write) {
    const std::size_t start = summary.size();
    write();
    if (summary.size() > start) {
      groups.push_back(Group{op, summary_start + start, summary.size() - start});
    }
  };
  group(mcap::Op::Schema, [&] {
    for (const auto& r : schema_records_) summary.raw(r.data(), r.size());
  });
  group(mcap::Op::Channel, [&] {
    for (const auto& r : channel_records_) summary.raw(r.data(), r.size());
  });
  group(mcap::Op::Statistics, [&] {
    const std::size_t record = summary.begin_record(mcap::Op::Statistics);
    summary.put(message_count_);
    summary.put(static_cast<std::uint16_t>(schema_records_.size()));
    summary.put(static_cast<std::uint32_t>(channel_records_.size()));
    summary.put(std::uint32_t{0});  // attachments
    summary.put(static_cast<std::uint32_t>(metadata_.size()));
    summary.put(static_cast<std::uint32_t>(chunks_.size()));
    summary.put(message_count_ > 0 ? first_time_ : std::uint64_t{0});
    summary.put(last_time_);
    const std::size_t map = summary.begin_block();
    for (std::size_t channel = 1; channel < channel_counts_.size(); ++channel) {
      summary.put(static_cast<std::uint16_t>(channel));
      summary.put(channel_counts_[channel]);
    }
    summary.end_block(map);
    summary.end_record(record);
  });
  group(mcap::Op::ChunkIndex, [&] {
    for (const ChunkIndex& c : chunks_) {
      const std::size_t record = summary.begin_record(mcap::Op::ChunkIndex);
      summary.put(c.start_time);
      summary.put(c.end_time);
      summary.put(c.offset);
      summary.put(c.length);
      const std::size_t map = summary.begin_block();
      for (const auto& [channel, offset] : c.index_offsets) {
        summary.put(channel);
        summary.put(offset);
      }
      summary.end_block(map);
      summary.put(c.index_length);
      summary.string("zstd");
      summary.put(c.compressed);
      summary.put(c.uncompressed);
      summary.end_record(record);
    }
  });
  group(mcap::Op::MetadataIndex, [&] {
    for (const MetadataIndex& m : metadata_) {
      const std::size_t record = summary.begin_record(mcap::Op::MetadataIndex);
      summary.put(m.offset);
      summary.put(m.length);
      summary.string(m.name);
      summary.end_record(record);
    }
  });
  const std::uint64_t offsets_start = summary_start + summary.size();
  for (const Group& g : groups) {
    const std::size_t record = summary.begin_record(mcap::Op::SummaryOffset);
    summary.put(static_cast<std::uint8_t>(g.op));
    summary.put(g.start);
    summary.put(g.length);
    summary.end_record(record);
  }
  const std::size_t footer = summary.begin_record(mcap::Op::Footer);
  summary.put(summary_start);
  summary.put(offsets_start);
  summary.patch64(footer, 8 + 8 + 4);  // the CRC covers the footer's length field
  summary.put(mcap::crc32(0, summary.data(), summary.size()));
  summary.end_record(footer);
  summary.raw(mcap::kMagic.data(), mcap::kMagic.size());
  write_out(summary.data(), summary.size());
  if (::fsync(fd_) != 0 && errno != EINVAL) {
    throw Error("cannot write recording " + path_.string() + ": " + errno_text(errno));
  }
  ::close(fd_);
  fd_ = -1;
}

}  // namespace horus::detail
