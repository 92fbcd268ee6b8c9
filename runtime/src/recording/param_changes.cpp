// The "/horus/params" channel of a recording: one JSON record per parameter change or starting
// value (docs/recording.md), written by recorder.cpp and read back for a replay.
#include "param_changes.hpp"

#include <cstdlib>
#include <optional>
#include <string_view>

#include "horus/error.hpp"
#include "horus/internal/json_record_cursor.hpp"
#include "horus/json_string.hpp"
#include "horus/params.hpp"
#include "mcap_format.hpp"

namespace horus::detail {
namespace {

std::optional<RecordedParamChange> parse_record(std::string_view text, const std::string& where) {
  JsonRecordCursor cursor(text);
  RecordedParamChange change;
  if (!cursor.take("{\"node\":")) return std::nullopt;
  std::optional<std::string> node = cursor.literal();
  if (!node || !cursor.take(",\"name\":")) return std::nullopt;
  std::optional<std::string> name = cursor.literal();
  if (!name || !cursor.take(",\"version\":")) return std::nullopt;
  const std::optional<std::uint64_t> version = cursor.number();
  if (!version) return std::nullopt;
  if (cursor.take(",\"cycle\":")) {
    change.cycle = cursor.number();
    if (!change.cycle) return std::nullopt;
  }
  change.start = cursor.take(",\"start\":true");
  if (!cursor.take(",\"source\":")) return std::nullopt;
  std::optional<std::string> source = cursor.literal();
  if (!source || !cursor.take(",\"msgpack\":")) return std::nullopt;
  const std::optional<std::string> encoded = cursor.literal();
  if (!encoded) return std::nullopt;
  change.node = std::move(*node);
  change.name = std::move(*name);
  change.version = *version;
  change.source = std::move(*source);
  change.value =
      mcap::base64_decode(*encoded, where + ": the value of " + change.node + "." + change.name);
  return change;
}

}  // namespace

std::string param_change_json(const RecordedParamChange& change) {
  std::string out = "{\"node\":" + json_string(change.node);
  out += ",\"name\":" + json_string(change.name);
  out += ",\"version\":" + std::to_string(change.version);
  if (change.cycle) out += ",\"cycle\":" + std::to_string(*change.cycle);
  if (change.start) out += ",\"start\":true";
  out += ",\"source\":" + json_string(change.source);
  out += ",\"msgpack\":\"" + mcap::base64_encode(change.value) + "\"";
  out += ",\"value\":";
  try {
    out += param_value_json(change.value);
  } catch (const ParamError&) {
    out += "null";  // never the case for a value a store accepted; the bytes are kept anyway
  }
  return out + "}";
}

}  // namespace horus::detail

namespace horus {

std::vector<RecordedParamChange> recorded_param_changes(const RecordingReader& recording) {
  std::vector<RecordedParamChange> changes;
  const RecordedChannel* channel = recording.channel(kParamsChannel);
  if (channel == nullptr) return changes;
  const std::string where = "recording channel " + std::string(kParamsChannel);
  for (const RecordedMessage* message : recording.messages_on(kParamsChannel)) {
    const std::string_view text(reinterpret_cast<const char*>(message->data.data()),
                                message->data.size());
    std::optional<RecordedParamChange> change = detail::parse_record(text, where);
    if (!change) {
      throw Error(where + ": malformed record (sequence " + std::to_string(message->sequence) +
                  "): " + std::string(text.substr(0, 120)));
    }
    changes.push_back(std::move(*change));
  }
  return changes;
}

}  // namespace horus
