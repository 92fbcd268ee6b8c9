// horus::RecordingReader: a linear read of an MCAP file (chunks decompressed with zstd, CRCs
// checked), enough for tests and deterministic replay; the summary is not needed to read it.
#include <zstd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/recording.hpp"
#include "mcap_format.hpp"

namespace horus {
namespace {

std::map<std::string, std::string> read_map(detail::mcap::Cursor& cursor) {
  const auto length = cursor.get<std::uint32_t>();
  const std::uint8_t* bytes = cursor.take(length);
  detail::mcap::Cursor entries(bytes, length, "map");
  std::map<std::string, std::string> map;
  while (entries.remaining() > 0) {
    std::string key = entries.string();
    map[std::move(key)] = entries.string();
  }
  return map;
}

std::string hex32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "%08x", value);
  return text;
}

}  // namespace

RecordingReader::RecordingReader(const std::filesystem::path& path) : path_(path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) {
    throw Error("cannot open recording " + path.string() + ": " + detail::errno_text(errno));
  }
  std::vector<std::uint8_t> file(static_cast<std::size_t>(in.tellg()));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(file.data()), static_cast<std::streamsize>(file.size()))) {
    throw Error("cannot read recording " + path.string() + ": " + detail::errno_text(errno));
  }
  const auto& magic = detail::mcap::kMagic;
  if (file.size() < magic.size() || std::memcmp(file.data(), magic.data(), magic.size()) != 0) {
    throw Error("recording " + path.string() + " is not an MCAP file (no magic)");
  }
  read_records(file.data() + magic.size(), file.size() - magic.size(), false);
}

const RecordedChannel* RecordingReader::channel(std::string_view topic) const {
  for (const auto& [id, channel] : channels_) {
    if (channel.topic == topic) return &channel;
  }
  return nullptr;
}

std::vector<const RecordedMessage*> RecordingReader::messages_on(std::string_view topic) const {
  std::vector<const RecordedMessage*> out;
  const RecordedChannel* found = channel(topic);
  if (found == nullptr) return out;
  for (const auto& m : messages_) {
    if (m.channel_id == found->id) out.push_back(&m);
  }
  return out;
}

void RecordingReader::read_records(const std::uint8_t* data, std::size_t size, bool in_chunk) {
  namespace mcap = detail::mcap;
  const std::string where = "recording " + path_.string();
  std::size_t at = 0;
  const std::uint8_t* file_start = data - mcap::kMagic.size();
  while (at < size) {
    if (size - at < mcap::kRecordPrefix) {
      if (in_chunk) throw Error(where + ": a chunk ends inside a record");
      return;  // cut short: what came before is all there is
    }
    const auto op = static_cast<mcap::Op>(data[at]);
    std::uint64_t length = 0;
    std::memcpy(&length, data + at + 1, 8);
    if (length > size - at - mcap::kRecordPrefix) {
      if (in_chunk) throw Error(where + ": a chunk ends inside a record");
      return;  // the last record was cut (kill -9 while it was written)
    }
    const std::uint8_t* content = data + at + mcap::kRecordPrefix;
    mcap::Cursor cursor(content, length, where);
    switch (op) {
      case mcap::Op::Schema: {
        RecordedSchema schema;
        schema.id = cursor.get<std::uint16_t>();
        schema.name = cursor.string();
        schema.encoding = cursor.string();
        schema.data = cursor.string();
        schemas_[schema.id] = std::move(schema);
        break;
      }
      case mcap::Op::Channel: {
        RecordedChannel channel;
        channel.id = cursor.get<std::uint16_t>();
        channel.schema_id = cursor.get<std::uint16_t>();
        channel.topic = cursor.string();
        channel.message_encoding = cursor.string();
        channel.metadata = read_map(cursor);
        const auto description = channel.metadata.find(std::string(mcap::kDescriptionKey));
        if (description != channel.metadata.end()) {
          channel.description = mcap::base64_decode(
              description->second,
              where + ": topic '" + channel.topic + "': " + std::string(mcap::kDescriptionKey));
        }
        channels_[channel.id] = std::move(channel);
        break;
      }
      case mcap::Op::Message: {
        RecordedMessage message;
        message.channel_id = cursor.get<std::uint16_t>();
        message.sequence = cursor.get<std::uint32_t>();
        message.log_time = cursor.get<std::uint64_t>();
        message.publish_time = cursor.get<std::uint64_t>();
        const std::size_t rest = cursor.remaining();
        const std::uint8_t* bytes = cursor.take(rest);
        message.data.assign(bytes, bytes + rest);
        if (channels_.count(message.channel_id) == 0) {
          throw Error(where + ": a message refers to channel " +
                      std::to_string(message.channel_id) + ", which no earlier record defines");
        }
        messages_.push_back(std::move(message));
        break;
      }
      case mcap::Op::Chunk: {
        cursor.get<std::uint64_t>();  // message start and end times
        cursor.get<std::uint64_t>();
        const auto uncompressed = cursor.get<std::uint64_t>();
        const auto crc = cursor.get<std::uint32_t>();
        const std::string compression = cursor.string();
        const auto compressed = cursor.get<std::uint64_t>();
        const std::uint8_t* records = cursor.take(compressed);
        std::vector<std::uint8_t> plain;
        if (compression == "zstd") {
          plain.resize(uncompressed);
          const std::size_t got = ZSTD_decompress(plain.data(), plain.size(), records, compressed);
          if (ZSTD_isError(got) != 0 || got != uncompressed) {
            throw Error(where + ": a chunk does not decompress (zstd: " +
                        (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size") + ")");
          }
        } else if (compression.empty()) {
          plain.assign(records, records + compressed);
        } else {
          throw Error(where + ": chunk compression '" + compression + "' is not supported");
        }
        if (crc != 0 && mcap::crc32(0, plain.data(), plain.size()) != crc) {
          throw Error(where + ": a chunk's CRC does not match (expected " + hex32(crc) + ")");
        }
        read_records(plain.data(), plain.size(), true);
        ++chunks_;
        break;
      }
      case mcap::Op::Metadata: {
        RecordedMetadata metadata;
        metadata.name = cursor.string();
        metadata.entries = read_map(cursor);
        metadata_.push_back(std::move(metadata));
        break;
      }
      case mcap::Op::DataEnd: {
        const auto crc = cursor.get<std::uint32_t>();
        const auto covered = static_cast<std::size_t>(data + at - file_start);
        if (crc != 0 && mcap::crc32(0, file_start, covered) != crc) {
          throw Error(where + ": the data section's CRC does not match (expected " + hex32(crc) +
                      ")");
        }
        complete_ = true;
        return;  // the summary repeats what the data section said
      }
      default:
        break;  // header, indexes and records HORUS does not write: nothing to take from them
    }
    at += mcap::kRecordPrefix + length;
  }
}

}  // namespace horus
