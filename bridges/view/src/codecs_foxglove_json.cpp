// The types Foxglove draws from JSON: a laser scan (foxglove.LaserScan), a pose in a frame
// (foxglove.PoseInFrame), a path (foxglove.PosesInFrame), a transform (foxglove.FrameTransform).
// Schemas and conversions are the recording export's (runtime/python/horus/foxglove.py:
// FOXGLOVE_SCHEMAS, _laser_scan, _pose_in_frame, _poses_in_frame, _frame_transform): the same
// field names, the same defaults (a frame name missing from the message is the topic's, a
// transform's parent "world"), invalid numbers as 0. A path's waypoints are 2D poses: position
// (x, y, 0), orientation the turn about +Z their heading theta gives (identity when theta is NaN
// or infinite).
#include <algorithm>
#include <cmath>
#include <string>

#include "codecs_internal.hpp"

namespace horus::view::detail {

namespace {

constexpr std::uint64_t kNanosecondsPerSecond = 1'000'000'000;

// -- schemas, written from the field lists Foxglove's documentation gives ----------------------

JsonValue string_schema() {
  JsonValue schema = JsonValue::object();
  schema.set("type", JsonValue::of_string("string"));
  return schema;
}

JsonValue number_schema() {
  JsonValue schema = JsonValue::object();
  schema.set("type", JsonValue::of_string("number"));
  return schema;
}

JsonValue object_schema(std::string_view title, JsonValue properties,
                        std::string_view description = "") {
  std::vector<std::string> names;
  for (const auto& member : properties.members) names.push_back(member.key);
  std::sort(names.begin(), names.end());
  JsonValue required = JsonValue::array();
  for (std::string& name : names) required.push(JsonValue::of_string(std::move(name)));
  JsonValue schema = JsonValue::object();
  schema.set("title", JsonValue::of_string(std::string(title)))
      .set("type", JsonValue::of_string("object"))
      .set("properties", std::move(properties))
      .set("required", std::move(required));
  if (!description.empty()) {
    schema.set("description", JsonValue::of_string(std::string(description)));
  }
  return schema;
}

JsonValue time_schema() {
  JsonValue sec = JsonValue::object();
  sec.set("type", JsonValue::of_string("integer")).set("minimum", JsonValue::of_unsigned(0));
  JsonValue nsec = JsonValue::object();
  nsec.set("type", JsonValue::of_string("integer"))
      .set("minimum", JsonValue::of_unsigned(0))
      .set("maximum", JsonValue::of_unsigned(kNanosecondsPerSecond - 1));
  JsonValue properties = JsonValue::object();
  properties.set("sec", std::move(sec)).set("nsec", std::move(nsec));
  return object_schema("time", std::move(properties));
}

JsonValue axes_schema(std::string_view title, std::string_view axes) {
  JsonValue properties = JsonValue::object();
  for (const char axis : axes) properties.set(std::string(1, axis), number_schema());
  return object_schema(title, std::move(properties));
}

JsonValue pose_schema() {
  JsonValue properties = JsonValue::object();
  properties.set("position", axes_schema("foxglove.Vector3", "xyz"))
      .set("orientation", axes_schema("foxglove.Quaternion", "xyzw"));
  return object_schema("foxglove.Pose", std::move(properties));
}

JsonValue poses_schema() {
  JsonValue schema = JsonValue::object();
  schema.set("type", JsonValue::of_string("array")).set("items", pose_schema());
  return schema;
}

JsonValue numbers_schema() {
  JsonValue schema = JsonValue::object();
  schema.set("type", JsonValue::of_string("array")).set("items", number_schema());
  return schema;
}

// -- conversions ----------------------------------------------------------------------------------

/// The member `name` of a message's value; CodecError when the type lacks it.
template <class Value>
Value& field(Value& value, std::string_view name, std::string_view type) {
  auto* found = value.find(name);
  if (found == nullptr) {
    throw CodecError(std::string(type) + " has no field '" + std::string(name) +
                     "' for the live view's Foxglove schema");
  }
  return *found;
}

/// A number Foxglove can read: HORUS marks an invalid range with NaN or an infinity, and JSON
/// has neither.
JsonValue finite(const JsonValue& value) {
  const double number = value.number();
  return JsonValue::of_float(std::isfinite(number) ? number : 0.0, value.single_precision);
}

/// A frame name from the message, or `fallback` when it has none (no field, or empty).
std::string frame_name(const JsonValue& plain, std::string_view name, std::string_view fallback) {
  const JsonValue* value = plain.find(name);
  if (value != nullptr && value->kind == JsonValue::Kind::String && !value->text.empty()) {
    return value->text;
  }
  return std::string(fallback);
}

JsonValue stamp(const JsonValue& plain) {
  const JsonValue* stamp_ns = plain.find("timestamp_ns");
  std::uint64_t ns = stamp_ns != nullptr && stamp_ns->kind == JsonValue::Kind::Unsigned
                         ? stamp_ns->unsigned_value
                         : 0;
  if (ns == 0) ns = now_ns();
  JsonValue time = JsonValue::object();
  time.set("sec", JsonValue::of_unsigned(ns / kNanosecondsPerSecond))
      .set("nsec", JsonValue::of_unsigned(ns % kNanosecondsPerSecond));
  return time;
}

/// Nanoseconds of a Foxglove time a viewer sent.
std::uint64_t stamp_ns(const JsonValue& time) {
  const JsonValue* sec = time.find("sec");
  const JsonValue* nsec = time.find("nsec");
  if (sec == nullptr || nsec == nullptr || !sec->is_number() || !nsec->is_number() ||
      sec->number() < 0 || nsec->number() < 0) {
    throw CodecError("timestamp: expected {\"sec\": integer, \"nsec\": integer}");
  }
  return static_cast<std::uint64_t>(sec->number()) * kNanosecondsPerSecond +
         static_cast<std::uint64_t>(nsec->number());
}

JsonValue axes(const JsonValue& values, std::string_view names, std::string_view type) {
  JsonValue out = JsonValue::object();
  if (values.kind == JsonValue::Kind::Array) {
    // An array field ([f64; 3]): its elements in order.
    for (std::size_t i = 0; i < names.size() && i < values.items.size(); ++i) {
      out.set(std::string(1, names[i]), finite(values.items[i]));
    }
  } else {
    for (const char axis : names) {
      out.set(std::string(1, axis), finite(field(values, std::string_view(&axis, 1), type)));
    }
  }
  return out;
}

JsonValue identity_pose() {
  JsonValue position = JsonValue::object();
  position.set("x", JsonValue::of_float(0.0))
      .set("y", JsonValue::of_float(0.0))
      .set("z", JsonValue::of_float(0.0));
  JsonValue orientation = JsonValue::object();
  orientation.set("x", JsonValue::of_float(0.0))
      .set("y", JsonValue::of_float(0.0))
      .set("z", JsonValue::of_float(0.0))
      .set("w", JsonValue::of_float(1.0));
  JsonValue pose = JsonValue::object();
  pose.set("position", std::move(position)).set("orientation", std::move(orientation));
  return pose;
}

/// The quaternion of a planar heading (a turn about +Z); a heading that is NaN or infinite as no
/// turn, as finite() reads it (foxglove.py's _yaw_orientation).
JsonValue yaw_orientation(double theta) {
  const double half = (std::isfinite(theta) ? theta : 0.0) / 2;
  JsonValue orientation = JsonValue::object();
  orientation.set("x", JsonValue::of_float(0.0))
      .set("y", JsonValue::of_float(0.0))
      .set("z", JsonValue::of_float(std::sin(half)))
      .set("w", JsonValue::of_float(std::cos(half)));
  return orientation;
}

/// The number a viewer sent as `source`'s member `key`; CodecError naming `where`.`key` else.
double sent_number(const JsonValue& source, std::string_view key, std::string_view where) {
  const JsonValue* number = source.find(key);
  if (number == nullptr || !number->is_number()) {
    throw CodecError(std::string(where) + "." + std::string(key) + ": expected a number");
  }
  return number->number();
}

/// Writes the numbers of a viewer's {x, y, z(, w)} into a message's value: an object of those
/// fields, or an array field in that order.
void set_axes(JsonValue& target, const JsonValue& source, std::string_view names,
              std::string_view where) {
  for (std::size_t i = 0; i < names.size(); ++i) {
    const std::string_view axis = names.substr(i, 1);
    const double number = sent_number(source, axis, where);
    JsonValue& slot = target.kind == JsonValue::Kind::Array && i < target.items.size()
                          ? target.items[i]
                          : field(target, axis, where);
    slot = JsonValue::of_float(number);
  }
}

enum class Shape { LaserScan, PoseInFrame, PosesInFrame, FrameTransform };

class FoxgloveJsonCodec final : public MessageCodec {
 public:
  FoxgloveJsonCodec(std::shared_ptr<const DescribedType> type, std::string_view schema_name,
                    std::string topic)
      : type_(std::move(type)), topic_(std::move(topic)) {
    shape_ = schema_name == "foxglove.LaserScan"      ? Shape::LaserScan
             : schema_name == "foxglove.PoseInFrame"  ? Shape::PoseInFrame
             : schema_name == "foxglove.PosesInFrame" ? Shape::PosesInFrame
                                                      : Shape::FrameTransform;
    std::string text;
    write_json(foxglove_json_schema(schema_name), text);
    schema_ = ChannelSchema{"json", std::string(schema_name), "jsonschema", std::move(text), false};
  }

  const ChannelSchema& schema() const override { return schema_; }

  void encode(std::span<const std::byte> frame, std::vector<std::byte>& payload) override {
    const std::span bytes(reinterpret_cast<const std::uint8_t*>(frame.data()), frame.size());
    const JsonValue plain = message_value(type_->description, *type_->message, bytes, false);
    text_.clear();
    write_json(convert(plain), text_);
    const auto* data = reinterpret_cast<const std::byte*>(text_.data());
    payload.assign(data, data + text_.size());
  }

  void decode(std::span<const std::byte> payload, std::vector<std::byte>& frame) override {
    if (shape_ == Shape::LaserScan) {
      throw CodecError("publishing laser scans from a viewer is not supported");
    }
    const JsonValue sent =
        parse_json(std::string_view(reinterpret_cast<const char*>(payload.data()), payload.size()));
    if (sent.kind != JsonValue::Kind::Object) {
      throw CodecError(schema_.schema_name + ": expected a JSON object");
    }
    const std::string& type_name = type_->message->name;
    // The message at its defaults, then what the viewer's message says of it.
    const std::vector<std::uint8_t> defaults = default_message(type_->description, *type_->message);
    JsonValue value = message_value(type_->description, *type_->message, defaults, false);
    if (const JsonValue* time = sent.find("timestamp"); time != nullptr) {
      if (value.find("timestamp_ns") != nullptr) {
        field(value, "timestamp_ns", type_name) = JsonValue::of_unsigned(stamp_ns(*time));
      }
    }
    if (shape_ == Shape::PoseInFrame) {
      const JsonValue& pose = field(sent, "pose", schema_.schema_name);
      JsonValue& target = field(value, "pose", type_name);
      set_axes(field(target, "position", type_name), field(pose, "position", "pose"), "xyz",
               "pose.position");
      set_axes(field(target, "orientation", type_name), field(pose, "orientation", "pose"), "xyzw",
               "pose.orientation");
      set_frame(value, "frame_id", sent, topic_);
    } else if (shape_ == Shape::PosesInFrame) {
      set_waypoints(value, field(sent, "poses", schema_.schema_name));
      set_frame(value, "frame_id", sent, topic_);
    } else {
      set_axes(field(value, "translation", type_name),
               field(sent, "translation", schema_.schema_name), "xyz", "translation");
      set_axes(field(value, "rotation", type_name), field(sent, "rotation", schema_.schema_name),
               "xyzw", "rotation");
      set_frame(value, "parent_frame_id", sent, "world");
      set_frame(value, "child_frame_id", sent, topic_);
    }
    encode_message(type_->description, *type_->message, value, frame);
  }

 private:
  JsonValue convert(const JsonValue& plain) const {
    const std::string& type_name = type_->message->name;
    JsonValue out = JsonValue::object();
    switch (shape_) {
      case Shape::LaserScan: {
        JsonValue ranges = JsonValue::array();
        const JsonValue& values = field(plain, "ranges", type_name);
        ranges.items.reserve(values.items.size());
        for (const JsonValue& range : values.items) ranges.push(finite(range));
        out.set("timestamp", stamp(plain))
            .set("frame_id", JsonValue::of_string(frame_name(plain, "frame_id", topic_)))
            .set("pose", identity_pose())
            .set("start_angle", finite(field(plain, "angle_min", type_name)))
            .set("end_angle", finite(field(plain, "angle_max", type_name)))
            .set("ranges", std::move(ranges))
            .set("intensities", JsonValue::array());
        return out;
      }
      case Shape::PoseInFrame: {
        const JsonValue& pose = field(plain, "pose", type_name);
        JsonValue converted = JsonValue::object();
        converted.set("position", axes(field(pose, "position", type_name), "xyz", type_name))
            .set("orientation", axes(field(pose, "orientation", type_name), "xyzw", type_name));
        out.set("timestamp", stamp(plain))
            .set("frame_id", JsonValue::of_string(frame_name(plain, "frame_id", topic_)))
            .set("pose", std::move(converted));
        return out;
      }
      case Shape::PosesInFrame: {
        const JsonValue& waypoints = field(plain, "waypoints", type_name);
        const std::size_t valid =
            std::min(static_cast<std::size_t>(field(plain, "waypoint_count", type_name).number()),
                     waypoints.items.size());
        JsonValue poses = JsonValue::array();
        poses.items.reserve(valid);
        for (std::size_t i = 0; i < valid; ++i) {
          const JsonValue& pose = field(waypoints.items[i], "pose", type_name);
          JsonValue position = JsonValue::object();
          position.set("x", finite(field(pose, "x", type_name)))
              .set("y", finite(field(pose, "y", type_name)))
              .set("z", JsonValue::of_float(0.0));
          JsonValue converted = JsonValue::object();
          converted.set("position", std::move(position))
              .set("orientation", yaw_orientation(field(pose, "theta", type_name).number()));
          poses.push(std::move(converted));
        }
        out.set("timestamp", stamp(plain))
            .set("frame_id", JsonValue::of_string(frame_name(plain, "frame_id", topic_)))
            .set("poses", std::move(poses));
        return out;
      }
      case Shape::FrameTransform:
        out.set("timestamp", stamp(plain))
            .set("parent_frame_id",
                 JsonValue::of_string(frame_name(plain, "parent_frame_id", "world")))
            .set("child_frame_id",
                 JsonValue::of_string(frame_name(plain, "child_frame_id", topic_)))
            .set("translation", axes(field(plain, "translation", type_name), "xyz", type_name))
            .set("rotation", axes(field(plain, "rotation", type_name), "xyzw", type_name));
        return out;
    }
    return out;
  }

  /// A viewer's poses as a path's first waypoints, the rest at their defaults: each pose's x and
  /// y, and the heading its orientation turns +X to in the XY plane (its yaw); z, roll and pitch
  /// have no place in a 2D waypoint.
  void set_waypoints(JsonValue& value, const JsonValue& poses) const {
    const std::string& type_name = type_->message->name;
    if (poses.kind != JsonValue::Kind::Array) throw CodecError("poses: expected an array");
    JsonValue& waypoints = field(value, "waypoints", type_name);
    if (poses.items.size() > waypoints.items.size()) {
      throw CodecError("poses: " + std::to_string(poses.items.size()) + " poses, more than the " +
                       std::to_string(waypoints.items.size()) + " waypoints a " + type_name +
                       " holds");
    }
    for (std::size_t i = 0; i < poses.items.size(); ++i) {
      const std::string where = "poses[" + std::to_string(i) + "]";
      const JsonValue& position = field(poses.items[i], "position", where);
      const JsonValue& orientation = field(poses.items[i], "orientation", where);
      const std::string at_orientation = where + ".orientation";
      const double x = sent_number(orientation, "x", at_orientation);
      const double y = sent_number(orientation, "y", at_orientation);
      const double z = sent_number(orientation, "z", at_orientation);
      const double w = sent_number(orientation, "w", at_orientation);
      JsonValue& pose = field(waypoints.items[i], "pose", type_name);
      set_axes(pose, position, "xy", where + ".position");
      field(pose, "theta", type_name) =
          JsonValue::of_float(std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)));
    }
    field(value, "waypoint_count", type_name) = JsonValue::of_unsigned(poses.items.size());
  }

  /// A frame name a viewer sent into the message's field of that name (when it has one); the
  /// name the field's absence stands for (`fallback`) is written as empty, so the round trip
  /// keeps the message as it was.
  static void set_frame(JsonValue& value, std::string_view name, const JsonValue& sent,
                        std::string_view fallback) {
    const JsonValue* given = sent.find(name);
    JsonValue* target = value.find(name);
    if (given == nullptr || target == nullptr) return;
    if (given->kind != JsonValue::Kind::String) {
      throw CodecError(std::string(name) + ": expected a string");
    }
    *target = JsonValue::of_string(given->text == fallback ? std::string() : given->text);
  }

  std::shared_ptr<const DescribedType> type_;
  std::string topic_;
  Shape shape_;
  ChannelSchema schema_;
  std::string text_;
};

}  // namespace

JsonValue foxglove_json_schema(std::string_view schema_name) {
  JsonValue properties = JsonValue::object();
  if (schema_name == "foxglove.LaserScan") {
    properties.set("timestamp", time_schema())
        .set("frame_id", string_schema())
        .set("pose", pose_schema())
        .set("start_angle", number_schema())
        .set("end_angle", number_schema())
        .set("ranges", numbers_schema())
        .set("intensities", numbers_schema());
    return object_schema(schema_name, std::move(properties),
                         "A single scan from a planar laser range-finder");
  }
  if (schema_name == "foxglove.PoseInFrame") {
    properties.set("timestamp", time_schema())
        .set("frame_id", string_schema())
        .set("pose", pose_schema());
    return object_schema(schema_name, std::move(properties),
                         "A timestamped pose for an object or reference frame in 3D space");
  }
  if (schema_name == "foxglove.PosesInFrame") {
    properties.set("timestamp", time_schema())
        .set("frame_id", string_schema())
        .set("poses", poses_schema());
    return object_schema(
        schema_name, std::move(properties),
        "An array of timestamped poses for an object or reference frame in 3D space");
  }
  if (schema_name == "foxglove.FrameTransform") {
    properties.set("timestamp", time_schema())
        .set("parent_frame_id", string_schema())
        .set("child_frame_id", string_schema())
        .set("translation", axes_schema("foxglove.Vector3", "xyz"))
        .set("rotation", axes_schema("foxglove.Quaternion", "xyzw"));
    return object_schema(schema_name, std::move(properties),
                         "A transform between two reference frames in 3D space");
  }
  throw CodecError("no Foxglove JSON schema called " + std::string(schema_name));
}

std::unique_ptr<MessageCodec> make_foxglove_json_codec(std::shared_ptr<const DescribedType> type,
                                                       std::string_view schema_name,
                                                       std::string topic) {
  return std::make_unique<FoxgloveJsonCodec>(std::move(type), schema_name, std::move(topic));
}

}  // namespace horus::view::detail
