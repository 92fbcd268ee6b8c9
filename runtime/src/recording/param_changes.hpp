// The "/horus/params" channel of a recording (docs/recording.md): its JSON Schema and records.
#pragma once

#include <string>
#include <string_view>

#include "horus/recording.hpp"

namespace horus::detail {

inline constexpr std::string_view kParamChangeSchemaName = "horus.recording.ParamChange";
inline constexpr std::string_view kParamChangeSchema =
    R"({"title":"horus.recording.ParamChange","type":"object",)"
    R"("properties":{"node":{"type":"string"},"name":{"type":"string"},)"
    R"("version":{"type":"integer"},"cycle":{"type":"integer"},"start":{"type":"boolean"},)"
    R"("source":{"type":"string"},"msgpack":{"type":"string","contentEncoding":"base64"},)"
    R"("value":{}},)"
    R"("required":["node","name","version","source","msgpack","value"]})";

/// One change as the channel's JSON record: node, name, version, cycle (when known), start (when
/// a starting value), source, the value's MessagePack bytes in base64 (what a replay applies)
/// and the value as JSON (what people and viewers read), in that order.
std::string param_change_json(const RecordedParamChange& change);

}  // namespace horus::detail
