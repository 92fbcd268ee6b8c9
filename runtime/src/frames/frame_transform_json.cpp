// Foxglove's FrameTransform as recordings and the live view write frames
// (horus/transform_feed.hpp), and read back for a replay.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>

#include "horus/internal/json_record_cursor.hpp"
#include "horus/json_string.hpp"
#include "horus/transform_feed.hpp"

namespace horus {
namespace {

constexpr std::int64_t kNanosecondsPerSecond = 1'000'000'000;

void append_real(std::string& out, double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.17g", value);
  out += text;
}

}  // namespace

std::string_view frame_transform_json_schema() noexcept {
  return R"({"title":"foxglove.FrameTransform","type":"object","properties":{)"
         R"("timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},)"
         R"("nsec":{"type":"integer","minimum":0,"maximum":999999999}}},)"
         R"("parent_frame_id":{"type":"string"},"child_frame_id":{"type":"string"},)"
         R"("translation":{"type":"object","properties":{"x":{"type":"number"},)"
         R"("y":{"type":"number"},"z":{"type":"number"}}},)"
         R"("rotation":{"type":"object","properties":{"x":{"type":"number"},)"
         R"("y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}})";
}

std::string frame_transform_json(const StampedTransform& transform) {
  // Foxglove's time has no sign: a stamp before the epoch is written as the epoch.
  const std::int64_t stamp = std::max<std::int64_t>(transform.stamp.count(), 0);
  std::string out = "{\"timestamp\":{\"sec\":" + std::to_string(stamp / kNanosecondsPerSecond) +
                    ",\"nsec\":" + std::to_string(stamp % kNanosecondsPerSecond) + "}";
  out += ",\"parent_frame_id\":" + json_string(transform.parent);
  out += ",\"child_frame_id\":" + json_string(transform.child);
  const Vector3& t = transform.transform.translation;
  const Quaternion& q = transform.transform.rotation;
  const char* const names[] = {"\"x\":", "\"y\":", "\"z\":", "\"w\":"};
  const double translation[] = {t.x, t.y, t.z};
  const double rotation[] = {q.x, q.y, q.z, q.w};
  out += ",\"translation\":{";
  for (int i = 0; i < 3; ++i) {
    out += i == 0 ? "" : ",";
    out += names[i];
    append_real(out, translation[i]);
  }
  out += "},\"rotation\":{";
  for (int i = 0; i < 4; ++i) {
    out += i == 0 ? "" : ",";
    out += names[i];
    append_real(out, rotation[i]);
  }
  return out + "}}";
}

std::optional<StampedTransform> frame_transform_from_json(std::string_view record,
                                                          std::string* why) {
  detail::JsonRecordCursor cursor(record);
  StampedTransform out;
  const auto refuse = [&](const char* what) -> std::optional<StampedTransform> {
    if (why != nullptr) *why = std::string("not a FrameTransform record: ") + what;
    return std::nullopt;
  };
  if (!cursor.take("{\"timestamp\":{\"sec\":")) return refuse("no timestamp first");
  const std::optional<std::uint64_t> sec = cursor.number();
  if (!sec || !cursor.take(",\"nsec\":")) return refuse("timestamp without sec");
  const std::optional<std::uint64_t> nsec = cursor.number();
  if (!nsec || *nsec >= kNanosecondsPerSecond || *sec > INT64_MAX / kNanosecondsPerSecond - 1) {
    return refuse("timestamp out of range");
  }
  out.stamp = std::chrono::nanoseconds(static_cast<std::int64_t>(*sec) * kNanosecondsPerSecond +
                                       static_cast<std::int64_t>(*nsec));
  if (!cursor.take("},\"parent_frame_id\":")) return refuse("no parent_frame_id");
  std::optional<std::string> parent = cursor.literal();
  if (!parent || !cursor.take(",\"child_frame_id\":")) return refuse("no child_frame_id");
  std::optional<std::string> child = cursor.literal();
  if (!child) return refuse("child_frame_id is not a string");
  out.parent = std::move(*parent);
  out.child = std::move(*child);
  Vector3& t = out.transform.translation;
  Quaternion& q = out.transform.rotation;
  double* const translation[] = {&t.x, &t.y, &t.z};
  double* const rotation[] = {&q.x, &q.y, &q.z, &q.w};
  const char* const names[] = {"\"x\":", "\"y\":", "\"z\":", "\"w\":"};
  if (!cursor.take(",\"translation\":{")) return refuse("no translation");
  for (int i = 0; i < 3; ++i) {
    const std::optional<double> value =
        cursor.take(i == 0 ? "" : ",") && cursor.take(names[i]) ? cursor.real() : std::nullopt;
    if (!value) return refuse("translation is not {x, y, z}");
    *translation[i] = *value;
  }
  if (!cursor.take("},\"rotation\":{")) return refuse("no rotation");
  for (int i = 0; i < 4; ++i) {
    const std::optional<double> value =
        cursor.take(i == 0 ? "" : ",") && cursor.take(names[i]) ? cursor.real() : std::nullopt;
    if (!value) return refuse("rotation is not {x, y, z, w}");
    *rotation[i] = *value;
  }
  if (!cursor.take("}}") || !cursor.at_end()) return refuse("trailing text");
  return out;
}

}  // namespace horus
