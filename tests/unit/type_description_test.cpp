// The C++ reader of the type description (horus/type_description.hpp): every standard type's
// carried description (TypeInfo<T>::description) agrees with the generated struct and its
// encoding, and descriptions built here by hand, hostile ones included, are read or refused as
// the format (docs/type-description.md) says.
#include <gtest/gtest.h>
#include <horus/codec.hpp>
#include <horus/msg.hpp>
#include <horus/msgpack.hpp>
#include <horus/type_description.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "every_field.hpp"

namespace {

using horus::MessageType;
using horus::TypeDescription;
using horus::TypeDescriptionError;
using horus::TypeRef;

// ---- Descriptions written by hand: a small MessagePack tree builder ----------------------------

/// A MessagePack value: nil, bool, integer, float, string, array or map (keys in order).
struct Value {
  using Array = std::vector<Value>;
  using Map = std::vector<std::pair<std::string, Value>>;
  std::variant<std::nullptr_t, bool, std::int64_t, double, std::string, Array, Map> data;

  Value(std::nullptr_t = nullptr) : data(nullptr) {}
  Value(bool value) : data(value) {}
  Value(int value) : data(std::int64_t{value}) {}
  Value(std::int64_t value) : data(value) {}
  Value(double value) : data(value) {}
  Value(const char* text) : data(std::string(text)) {}
  Value(std::string text) : data(std::move(text)) {}
  Value(Array array) : data(std::move(array)) {}
  Value(Map map) : data(std::move(map)) {}
};

Value map(std::initializer_list<std::pair<std::string, Value>> entries) {
  return Value(Value::Map(entries));
}
Value list(std::initializer_list<Value> elements) { return Value(Value::Array(elements)); }

void pack(msgpack::packer<msgpack::sbuffer>& packer, const Value& value) {
  std::visit(
      [&](const auto& v) {
        using V = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<V, std::nullptr_t>) {
          packer.pack_nil();
        } else if constexpr (std::is_same_v<V, bool>) {
          v ? packer.pack_true() : packer.pack_false();
        } else if constexpr (std::is_same_v<V, std::int64_t>) {
          packer.pack_int64(v);
        } else if constexpr (std::is_same_v<V, double>) {
          packer.pack_double(v);
        } else if constexpr (std::is_same_v<V, std::string>) {
          packer.pack(v);
        } else if constexpr (std::is_same_v<V, Value::Array>) {
          packer.pack_array(static_cast<std::uint32_t>(v.size()));
          for (const Value& element : v) pack(packer, element);
        } else {
          packer.pack_map(static_cast<std::uint32_t>(v.size()));
          for (const auto& [key, element] : v) {
            packer.pack(key);
            pack(packer, element);
          }
        }
      },
      value.data);
}

std::string bytes_of(const Value& value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  pack(packer, value);
  return std::string(buffer.data(), buffer.size());
}

Value primitive(const char* name) { return map({{"kind", "primitive"}, {"name", name}}); }
Value named(const char* kind, const char* name) { return map({{"kind", kind}, {"name", name}}); }
Value wrapped(const char* kind, Value element) {
  return map({{"kind", kind}, {"element", std::move(element)}});
}
Value array_of(Value element, int length) {
  return map({{"kind", "array"}, {"element", std::move(element)}, {"length", length}});
}

Value field(const char* name, Value type, Value offset = nullptr, Value size = nullptr,
            Value default_value = nullptr) {
  return map({{"name", name},
              {"type", std::move(type)},
              {"offset", std::move(offset)},
              {"size", std::move(size)},
              {"default", std::move(default_value)},
              {"unit", ""}});
}

Value message(const char* name, Value::Array fields, Value size = nullptr,
              Value alignment = nullptr) {
  const bool pod = !std::holds_alternative<std::nullptr_t>(size.data);
  return map({{"kind", "message"},
              {"name", name},
              {"package", "t"},
              {"fingerprint", "0x00000000000000ab"},
              {"tier", pod ? "pod" : "serialized"},
              {"size", std::move(size)},
              {"alignment", std::move(alignment)},
              {"fields", Value(std::move(fields))},
              {"constants", list({})},
              {"padding", list({})},
              {"summary", list({})},
              {"topic", nullptr},
              {"schema", ""}});
}

Value color_enum() {
  return map({{"kind", "enum"},
              {"name", "t.Color"},
              {"package", "t"},
              {"fingerprint", "0x0000000000000001"},
              {"underlying", "u8"},
              {"values", list({map({{"name", "Red"}, {"value", 0}}),
                               map({{"name", "Green"}, {"value", 1}})})}});
}

std::string described(const char* root, Value::Array types, const char* format = "horus.typedesc",
                      int version = 1) {
  return bytes_of(map({{"format", format},
                       {"version", version},
                       {"root", root},
                       {"types", Value(std::move(types))}}));
}

/// t.Point {x: f32 at 0, y: f32 at 4, color: Color at 8 (default Green), name: string<3> at 9}
std::string pod_point() {
  return described(
      "t.Point",
      {color_enum(),
       message("t.Point",
               {field("x", primitive("f32"), 0, 4, 1.5), field("y", primitive("f32"), 4, 4),
                field("color", named("enum", "t.Color"), 8, 1, "Green"),
                field("name", map({{"kind", "string"}, {"capacity", 3}}), 9, 3, "ab")},
               12, 4)});
}

/// t.Bag {tags: Vec<String>, data: bytes, maybe: Option<i16>, colors: [Color; 2], inner: t.Inner}
/// t.Inner {flag: bool, count: u32 = 7}
std::string serialized_bag() {
  return described("t.Bag",
                   {color_enum(),
                    message("t.Inner", {field("flag", primitive("bool")),
                                        field("count", primitive("u32"), {}, {}, 7)}),
                    message("t.Bag", {field("tags", wrapped("vec", map({{"kind", "string"}}))),
                                      field("data", map({{"kind", "bytes"}})),
                                      field("maybe", wrapped("optional", primitive("i16"))),
                                      field("colors", array_of(named("enum", "t.Color"), 2)),
                                      field("inner", named("message", "t.Inner"))})});
}

std::span<const std::uint8_t> as_span(const std::string& bytes) {
  return {reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()};
}

std::string refusal(const std::string& bytes) {
  try {
    TypeDescription::decode(bytes);
  } catch (const TypeDescriptionError& e) {
    return e.what();
  }
  return "(decoded)";
}

TEST(TypeDescription, ReadsAPodMessageWithItsLayout) {
  const TypeDescription description = TypeDescription::decode(pod_point());
  EXPECT_EQ(description.version, 1);
  const MessageType& point = description.root_message();
  EXPECT_EQ(point.name, "t.Point");
  EXPECT_EQ(point.fingerprint, 0xabU);
  EXPECT_TRUE(point.is_pod);
  EXPECT_EQ(point.size, 12U);
  EXPECT_EQ(point.alignment, 4U);
  ASSERT_EQ(point.fields.size(), 4U);
  EXPECT_EQ(point.fields[1].offset, 4U);
  EXPECT_EQ(point.find_field("name")->type.kind, TypeRef::Kind::FixedString);
  EXPECT_EQ(point.find_field("name")->type.length, 3U);
  EXPECT_EQ(point.find_field("nothing"), nullptr);
  const TypeRef& color = point.fields[2].type;
  ASSERT_EQ(color.kind, TypeRef::Kind::Enum);
  EXPECT_EQ(description.enumeration(color).name, "t.Color");
  EXPECT_EQ(description.find_enum("t.Color")->find_value(1)->name, "Green");
  EXPECT_EQ(description.find_message("t.Color"), nullptr);
  EXPECT_THROW(description.message("t.Nope"), TypeDescriptionError);
}

TEST(TypeDescription, PrintsAndWritesPodMessages) {
  const TypeDescription description = TypeDescription::decode(pod_point());
  const MessageType& point = description.root_message();
  EXPECT_EQ(horus::zero_message(description, point), std::vector<std::uint8_t>(12, 0));
  const std::vector<std::uint8_t> defaults = horus::default_message(description, point);
  EXPECT_EQ(horus::to_json(description, point, defaults),
            R"({"x": 1.5, "y": 0, "color": "Green", "name": "ab"})");
  std::vector<std::uint8_t> other = defaults;
  other[8] = 9;  // outside the enum: its number
  other[9] = 'x';
  other[10] = 'y';
  other[11] = 'z';  // a full string<3> has no NUL
  EXPECT_EQ(horus::to_json(description, point, other),
            R"({"x": 1.5, "y": 0, "color": 9, "name": "xyz"})");
  EXPECT_THROW(horus::to_json(description, point, std::span(defaults).first(11)),
               horus::DecodeError);
}

TEST(TypeDescription, PrintsAndWritesSerializedMessages) {
  const TypeDescription description = TypeDescription::decode(serialized_bag());
  const MessageType& bag = description.root_message();
  EXPECT_FALSE(bag.is_pod);
  EXPECT_TRUE(bag.find_field("data")->type.is_byte_block());
  const std::vector<std::uint8_t> zero = horus::zero_message(description, bag);
  EXPECT_EQ(horus::to_json(description, bag, zero),
            R"({"tags": [], "data": [], "maybe": null, "colors": ["Red", "Red"], )"
            R"("inner": {"flag": false, "count": 0}})");
  EXPECT_EQ(horus::to_json(description, bag, horus::default_message(description, bag)),
            R"({"tags": [], "data": [], "maybe": null, "colors": ["Red", "Red"], )"
            R"("inner": {"flag": false, "count": 7}})");

  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack_array(5);
  packer.pack(std::vector<std::string>{"a\"b", "\xff", "\xc3\xa9"});
  packer.pack(std::vector<std::uint8_t>{1, 2});
  packer.pack(std::int16_t{-3});
  packer.pack_array(2);
  packer.pack(std::uint8_t{1});
  packer.pack(std::uint8_t{0});
  packer.pack_array(2);
  packer.pack(true);
  packer.pack(std::uint32_t{4000000000U});
  const std::string bytes(buffer.data(), buffer.size());
  EXPECT_EQ(horus::to_json(description, bag, as_span(bytes)),
            "{\"tags\": [\"a\\\"b\", \"\xef\xbf\xbd\", \"\xc3\xa9\"], \"data\": [1, 2], "
            "\"maybe\": -3, \"colors\": [\"Green\", \"Red\"], "
            "\"inner\": {\"flag\": true, \"count\": 4000000000}}");
}

TEST(TypeDescription, RefusesMessageBytesThatDoNotMatch) {
  const TypeDescription description = TypeDescription::decode(serialized_bag());
  const MessageType& bag = description.root_message();
  const std::vector<std::uint8_t> zero = horus::zero_message(description, bag);
  const auto refused = [&](std::span<const std::uint8_t> bytes) {
    EXPECT_THROW(horus::to_json(description, bag, bytes), horus::DecodeError);
  };
  for (std::size_t cut = 0; cut < zero.size(); ++cut) refused(std::span(zero).first(cut));
  std::vector<std::uint8_t> trailing = zero;
  trailing.push_back(0);
  refused(trailing);
  std::vector<std::uint8_t> wrong = zero;
  wrong.back() = 0xc3;  // count: true instead of an integer
  refused(wrong);
  // Every single-byte change of a filled message either walks or is refused with a DecodeError.
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack_array(5);
  packer.pack(std::vector<std::string>{"one", "two"});
  packer.pack(std::vector<std::uint8_t>{1, 2, 3});
  packer.pack(std::int16_t{-300});
  packer.pack_array(2);
  packer.pack(std::uint8_t{1});
  packer.pack(std::uint8_t{0});
  packer.pack_array(2);
  packer.pack(true);
  packer.pack(std::uint32_t{70000});
  const std::vector<std::uint8_t> filled(buffer.data(), buffer.data() + buffer.size());
  for (std::size_t at = 0; at < filled.size(); ++at) {
    for (const std::uint8_t flip : {0x01, 0x10, 0x80, 0xff}) {
      std::vector<std::uint8_t> changed = filled;
      changed[at] ^= flip;
      try {
        horus::to_json(description, bag, changed);
      } catch (const horus::DecodeError&) {
      }
    }
  }
  // An array header claiming 2^32 - 1 elements in a few bytes: refused, never allocated.
  refused(std::vector<std::uint8_t>{0xdd, 0xff, 0xff, 0xff, 0xff, 0x00});
  refused(std::vector<std::uint8_t>{0x95, 0x90, 0xc4, 0x00, 0xc0, 0x92, 0x00, 0x00, 0x92, 0xc2,
                                    0xcf, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00});
}

TEST(TypeDescription, ReadsTheDescribeFormWithoutARoot) {
  const std::string bytes = bytes_of(map(
      {{"format", "horus.typedesc"},
       {"version", 1},
       {"future_key", list({1, 2})},
       {"types", list({map({{"kind", "node"}, {"name", "t.Driver"}}),
                       map({{"kind", "service"},
                            {"name", "t.Add"},
                            {"package", "t"},
                            {"fingerprint", "0x00000000000000ff"},
                            {"request", "t.Add_Request"},
                            {"response", "t.Add_Response"},
                            {"request_topic", "add/request"},
                            {"response_topic", "add/response"}}),
                       message("t.Add_Request", {field("a", primitive("i64"), 0, 8)}, 8, 8)})}}));
  const TypeDescription description = TypeDescription::decode(bytes);
  EXPECT_TRUE(description.root.empty());
  EXPECT_THROW(description.root_message(), TypeDescriptionError);
  ASSERT_NE(description.find_service("t.Add"), nullptr);
  EXPECT_EQ(description.find_service("t.Add")->response_topic, "add/response");
  EXPECT_EQ(description.find_service("t.Add")->fingerprint, 0xffU);
  EXPECT_EQ(description.message("t.Add_Request").size, 8U);
}

TEST(TypeDescription, EncodesTheDescribeFormBackToTheSameTree) {
  const std::string bytes = bytes_of(map(
      {{"format", "horus.typedesc"},
       {"version", 1},
       {"types", list({map({{"kind", "service"},
                            {"name", "t.Add"},
                            {"package", "t"},
                            {"fingerprint", "0x00000000000000ff"},
                            {"request", "t.Add_Request"},
                            {"response", "t.Add_Response"},
                            {"request_topic", "add/request"},
                            {"response_topic", "add/response"}}),
                       message("t.Add_Request", {field("a", primitive("i64"), 0, 8)}, 8, 8)})}}));
  const std::string encoded = TypeDescription::decode(bytes).encode();
  const TypeDescription again = TypeDescription::decode(encoded);
  EXPECT_TRUE(again.root.empty());
  ASSERT_EQ(again.services.size(), 1U);
  EXPECT_EQ(again.services[0].request_topic, "add/request");
  ASSERT_EQ(again.messages.size(), 1U);
  EXPECT_EQ(again.messages[0].fields[0].offset, 0U);
  EXPECT_EQ(again.encode(), encoded) << "encoding is not deterministic";
}

TEST(TypeDescription, RefusesToEncodeARootThatIsNotInItsTypes) {
  TypeDescription description;
  description.root = "t.Missing";
  EXPECT_THROW(description.encode(), TypeDescriptionError);
}

TEST(TypeDescription, RefusesWhatIsNotADescriptionItReads) {
  EXPECT_NE(refusal("\xc1").find("not a valid MessagePack"), std::string::npos);
  EXPECT_NE(refusal(bytes_of(list({}))).find("expected a map"), std::string::npos);
  EXPECT_NE(refusal(described("t.X", {}, "other.format")).find("\"other.format\" is not"),
            std::string::npos);
  EXPECT_NE(refusal(described("t.X", {}, "horus.typedesc", 2)).find("2 is newer"),
            std::string::npos);
  EXPECT_NE(refusal(described("t.X", {})).find("root: t.X is not in types"), std::string::npos);
  const std::string unknown =
      refusal(described("t.A", {message("t.A", {field("b", named("message", "t.B"))})}));
  EXPECT_NE(unknown.find("types[0].fields[0].type: names message t.B, which is not in types"),
            std::string::npos)
      << unknown;
  EXPECT_NE(refusal(described("t.A", {color_enum(),
                                      message("t.A", {field("c", named("message", "t.Color"))})}))
                .find("names message t.Color, which is not a message"),
            std::string::npos);
  const std::string cycle = refusal(
      described("t.A", {message("t.A", {field("b", named("message", "t.B"))}),
                        message("t.B", {field("a", wrapped("vec", named("message", "t.A")))})}));
  EXPECT_NE(cycle.find("contains itself"), std::string::npos) << cycle;
  const std::string outside =
      refusal(described("t.P", {message("t.P", {field("x", primitive("f64"), 4, 8)}, 8, 8)}));
  EXPECT_NE(outside.find("ends past the message's 8 bytes"), std::string::npos) << outside;
  const std::string overlap = refusal(described(
      "t.P",
      {message("t.P", {field("x", primitive("u32"), 0), field("y", primitive("u32"), 2)}, 8, 4)}));
  EXPECT_NE(overlap.find("overlap"), std::string::npos) << overlap;
  const std::string serialized_in_pod =
      refusal(described("t.P", {message("t.P", {field("s", map({{"kind", "string"}}), 0)}, 8, 8)}));
  EXPECT_NE(serialized_in_pod.find("without a fixed layout"), std::string::npos);
  EXPECT_NE(refusal(described("t.A", {message("t.A", {field("x", primitive("u7"))})}))
                .find("\"u7\" is not a primitive"),
            std::string::npos);
}

TEST(TypeDescription, RefusesWrongTypesInTheTree) {
  const Value good_type = primitive("u8");
  const std::vector<std::pair<std::string, Value>> bad_fields{
      {"a kind that is a number", map({{"kind", 3}})},
      {"a name that is a list", map({{"kind", "message"}, {"name", list({})}})},
      {"a length that is negative",
       map({{"kind", "array"}, {"element", good_type}, {"length", -1}})},
      {"a length that is a string",
       map({{"kind", "array"}, {"element", good_type}, {"length", "3"}})},
      {"no element", map({{"kind", "vec"}})},
      {"a type that is a string", "u8"},
      {"an unknown kind", map({{"kind", "tuple"}})},
  };
  for (const auto& [what, type] : bad_fields) {
    EXPECT_THROW(TypeDescription::decode(described("t.A", {message("t.A", {field("x", type)})})),
                 TypeDescriptionError)
        << what;
  }
  EXPECT_THROW(TypeDescription::decode(bytes_of(
                   map({{"format", "horus.typedesc"}, {"version", 1}, {"types", "none"}}))),
               TypeDescriptionError);
  EXPECT_THROW(TypeDescription::decode(bytes_of(
                   map({{"format", "horus.typedesc"}, {"version", "1"}, {"types", list({})}}))),
               TypeDescriptionError);
  EXPECT_THROW(TypeDescription::decode(described("t.A", {list({})})), TypeDescriptionError);
}

TEST(TypeDescription, RefusesTruncatedDescriptionsAtEveryLength) {
  const std::string whole = serialized_bag();
  for (std::size_t cut = 0; cut < whole.size(); ++cut) {
    EXPECT_THROW(TypeDescription::decode(std::string_view(whole).substr(0, cut)),
                 TypeDescriptionError)
        << "cut at " << cut;
  }
  // Every single-byte change either decodes or is refused: never a crash or another exception.
  for (std::size_t at = 0; at < whole.size(); ++at) {
    std::string changed = whole;
    changed[at] = static_cast<char>(changed[at] ^ 0x5a);
    try {
      const TypeDescription description = TypeDescription::decode(changed);
      if (const MessageType* bag = description.find_message("t.Bag")) {
        horus::zero_message(description, *bag);
      }
    } catch (const TypeDescriptionError&) {
    }
  }
}

TEST(TypeDescription, RefusesDeepNestingAndHugeCounts) {
  Value deep = primitive("u8");
  for (int i = 0; i < 200; ++i) deep = wrapped("vec", deep);
  EXPECT_NE(refusal(described("t.A", {message("t.A", {field("x", deep)})})).find("nest deeper"),
            std::string::npos);

  Value::Array chain;
  for (int i = 0; i < 100; ++i) {
    const std::string name = "t.M" + std::to_string(i);
    const std::string inner = "t.M" + std::to_string(i - 1);
    Value::Array fields;
    if (i > 0) fields.push_back(field("m", named("message", inner.c_str())));
    chain.push_back(message(name.c_str(), std::move(fields)));
  }
  EXPECT_NE(refusal(described("t.M99", chain)).find("nest deeper"), std::string::npos);

  // Counts beyond the caps, and counts that claim more elements than the bytes hold.
  EXPECT_THROW(TypeDescription::decode(described(
                   "t.A", {message("t.A", {field("x", array_of(primitive("u8"), 1 << 30))})})),
               TypeDescriptionError);
  EXPECT_THROW(TypeDescription::decode(described("t.P", {message("t.P", {}, 1 << 30, 1)})),
               TypeDescriptionError);
  EXPECT_THROW(TypeDescription::decode(std::string("\xdf\xff\xff\xff\xff", 5)),
               TypeDescriptionError);
  EXPECT_THROW(TypeDescription::decode(std::string(horus::kMaxDescriptionBytes + 1, '\x90')),
               TypeDescriptionError);

  // Arrays within the caps that multiply past them: refused before anything is written.
  const TypeDescription huge = TypeDescription::decode(described(
      "t.A",
      {message("t.A", {field("x", array_of(array_of(primitive("u32"), 1 << 20), 1 << 20))})}));
  EXPECT_THROW(horus::zero_message(huge, huge.root_message()), TypeDescriptionError);
  // ... and messages shared many times over are counted once each.
  Value::Array wide;
  for (int i = 0; i < 64; ++i) {
    const std::string name = "t.W" + std::to_string(i);
    const std::string inner = "t.W" + std::to_string(i - 1);
    Value::Array fields;
    if (i > 0) {
      fields.push_back(field("a", named("message", inner.c_str())));
      fields.push_back(field("b", named("message", inner.c_str())));
    }
    wide.push_back(message(name.c_str(), std::move(fields)));
  }
  const TypeDescription doubling = TypeDescription::decode(described("t.W63", wide));
  EXPECT_THROW(horus::zero_message(doubling, doubling.root_message()), TypeDescriptionError);
}

// ---- Every standard type's carried description against the generated code ------------------

template <class... Ts>
struct TypeList {};

using namespace horus::msg;

using StandardMessages =
    TypeList<CmdVel, Twist, Pose2D, TransformStamped, Point3, Vector3, Quaternion, Pose3D,
             PoseStamped, PoseWithCovariance, TwistWithCovariance, Accel, AccelStamped, LaserScan,
             Imu, Odometry, Range, BatteryState, NavSatFix, JointState, MagneticField, Temperature,
             FluidPressure, Illuminance, MotorCommand, DifferentialDriveCommand, ServoCommand,
             JointCommand, PidConfig, TrajectoryPoint, CompressedImage, CameraInfo,
             RegionOfInterest, StereoInfo, ImageDescriptor, DepthImageDescriptor,
             PointCloudDescriptor, PoolBlock, TensorDescriptor, BoundingBox2D, BoundingBox3D,
             Detection, Detection3D, PointXYZ, PointXYZRGB, PointXYZI, Goal, GoalResult, Waypoint,
             Path, PathPlan, OccupancyGrid, CostMap, VelocityObstacle, VelocityObstacles, Heartbeat,
             NodeHeartbeat, Status, EmergencyStop, SafetyStatus, ResourceUsage, DiagnosticValue,
             DiagnosticReport, DiagnosticStatus, WrenchStamped, ImpedanceParameters, ForceCommand,
             ContactInfo, HapticFeedback, TactileArray, JoystickInput, KeyboardInput,
             SegmentationMask, Landmark, Landmark3D, LandmarkArray, TrackedObject, TrackingHeader,
             Clock, TimeReference, AudioFrame, GenericMessage>;

/// Field offsets of a POD message as the compiler laid them out.
template <class T>
std::vector<std::size_t> compiled_offsets() {
  std::vector<std::size_t> offsets;
  const auto value = std::make_unique<T>();
  const auto* base = reinterpret_cast<const unsigned char*>(value.get());
  horus::TypeInfo<T>::visit(*value, [&](std::string_view, const auto& field) {
    offsets.push_back(static_cast<std::size_t>(
        reinterpret_cast<const unsigned char*>(std::addressof(field)) - base));
  });
  return offsets;
}

/// Whether a field of `type`, or of a message it holds, has a schema default.
bool has_defaults(const TypeDescription& description, const MessageType& type) {
  for (const horus::MessageField& field : type.fields) {
    const TypeRef* inner = &field.type;
    while (inner->element) inner = inner->element.get();
    if (!field.default_value.empty() || (inner->kind == TypeRef::Kind::Message &&
                                         has_defaults(description, description.message(*inner)))) {
      return true;
    }
  }
  return false;
}

template <class T>
void check_standard_type() {
  using Info = horus::TypeInfo<T>;
  SCOPED_TRACE(std::string(Info::name));
  const TypeDescription description = TypeDescription::decode(Info::description);
  ASSERT_EQ(description.root, Info::name);
  const MessageType& type = description.root_message();
  EXPECT_EQ(type.fingerprint, Info::fingerprint);
  EXPECT_EQ(type.is_pod, Info::is_pod);
  ASSERT_EQ(type.fields.size(), Info::field_count);
  if constexpr (Info::is_pod) {
    EXPECT_EQ(type.size, sizeof(T));
    EXPECT_EQ(type.alignment, alignof(T));
    const std::vector<std::size_t> offsets = compiled_offsets<T>();
    for (std::size_t i = 0; i < offsets.size(); ++i) {
      EXPECT_EQ(type.fields[i].offset, offsets[i]) << type.fields[i].name;
    }
    ASSERT_EQ(type.padding.size(), Info::padding.size());
    for (std::size_t i = 0; i < type.padding.size(); ++i) {
      EXPECT_EQ(type.padding[i].offset, Info::padding[i].offset);
      EXPECT_EQ(type.padding[i].size, Info::padding[i].size);
    }
  }
  const auto made = std::make_unique<T>();
  const std::vector<std::uint8_t> encoded = horus::encode(*made);
  EXPECT_EQ(horus::default_message(description, type), encoded)
      << "default_message differs from the encoding of a default " << Info::name;
  // The zero message decodes as the type, and is the default one wherever no field has a default.
  const std::vector<std::uint8_t> zero = horus::zero_message(description, type);
  EXPECT_NO_THROW(horus::decode<T>(zero));
  if (!has_defaults(description, type)) {
    EXPECT_EQ(zero, encoded);
  }

  const std::string json = horus::to_json(description, type, encoded);
  for (const horus::MessageField& field : type.fields) {
    EXPECT_NE(json.find("\"" + field.name + "\": "), std::string::npos)
        << field.name << " missing from " << json.substr(0, 200);
  }
}

template <class... Ts>
void check_standard_types(TypeList<Ts...>) {
  (check_standard_type<Ts>(), ...);
}

/// Writes back what the walk reports as MessagePack, knowing only the TypeRefs it is given: the
/// bytes equal msgpack-cxx's packing of the same value when every value and type arrived.
class Repacker final : public horus::MessageVisitor {
 public:
  std::vector<std::uint8_t> bytes() const {
    const auto* data = reinterpret_cast<const std::uint8_t*>(buffer_.data());
    return {data, data + buffer_.size()};
  }

  void begin_message(const MessageType& type) override {
    packer_.pack_array(static_cast<std::uint32_t>(type.fields.size()));
  }
  void end_message(const MessageType&) override {}
  void field(const horus::MessageField&) override {}
  void boolean(bool value) override { value ? packer_.pack_true() : packer_.pack_false(); }
  void unsigned_integer(const TypeRef& type, std::uint64_t value) override {
    integer(type.primitive, value);
  }
  void signed_integer(const TypeRef& type, std::int64_t value) override {
    integer(type.primitive, static_cast<std::uint64_t>(value));
  }
  void floating(const TypeRef& type, double value) override {
    if (type.primitive == horus::Primitive::F32) {
      packer_.pack_float(static_cast<float>(value));
    } else {
      packer_.pack_double(value);
    }
  }
  void enumerator(const horus::EnumType& type, std::int64_t value) override {
    integer(type.underlying, static_cast<std::uint64_t>(value));
  }
  void string(const TypeRef&, std::string_view text) override {
    packer_.pack_str(static_cast<std::uint32_t>(text.size()));
    packer_.pack_str_body(text.data(), static_cast<std::uint32_t>(text.size()));
  }
  void bytes(const TypeRef&, std::span<const std::uint8_t> data) override {
    packer_.pack_bin(static_cast<std::uint32_t>(data.size()));
    packer_.pack_bin_body(reinterpret_cast<const char*>(data.data()),
                          static_cast<std::uint32_t>(data.size()));
  }
  void begin_sequence(const TypeRef&, std::size_t count) override {
    packer_.pack_array(static_cast<std::uint32_t>(count));
  }
  void end_sequence(const TypeRef&) override {}
  void begin_optional(const TypeRef&, bool present) override {
    if (!present) packer_.pack_nil();
  }
  void end_optional(const TypeRef&) override {}

 private:
  void integer(horus::Primitive primitive, std::uint64_t bits) {
    switch (primitive) {
      case horus::Primitive::U8:
        packer_.pack_uint8(static_cast<std::uint8_t>(bits));
        return;
      case horus::Primitive::U16:
        packer_.pack_uint16(static_cast<std::uint16_t>(bits));
        return;
      case horus::Primitive::U32:
        packer_.pack_uint32(static_cast<std::uint32_t>(bits));
        return;
      case horus::Primitive::U64:
        packer_.pack_uint64(bits);
        return;
      case horus::Primitive::I8:
        packer_.pack_int8(static_cast<std::int8_t>(bits));
        return;
      case horus::Primitive::I16:
        packer_.pack_int16(static_cast<std::int16_t>(bits));
        return;
      case horus::Primitive::I32:
        packer_.pack_int32(static_cast<std::int32_t>(bits));
        return;
      default:
        packer_.pack_int64(static_cast<std::int64_t>(bits));
    }
  }

  msgpack::sbuffer buffer_;
  msgpack::packer<msgpack::sbuffer> packer_{buffer_};
};

template <class T>
void check_walk(const TypeDescription& description) {
  SCOPED_TRACE(std::string(horus::TypeInfo<T>::name));
  auto value = std::make_unique<T>();
  std::uint64_t k = 1;
  horus_test::fill_every_field(*value, k, horus_test::Enums::Alternate);
  Repacker repacker;
  horus::walk_message(description, description.root_message(), horus::encode(*value), repacker);
  EXPECT_EQ(repacker.bytes(), horus::detail::Msgpack<T>::pack(*value))
      << "the walk of a filled " << horus::TypeInfo<T>::name << " lost or changed a value";
}

template <class... Ts>
void check_walks(TypeList<Ts...>) {
  (check_walk<Ts>(TypeDescription::decode(horus::TypeInfo<Ts>::description)), ...);
}

TEST(StandardTypeDescriptions, AgreeWithTheGeneratedCode) {
  check_standard_types(StandardMessages{});
}

TEST(StandardTypeDescriptions, WalkEveryValueOfFilledMessages) { check_walks(StandardMessages{}); }

/// decode() then encode() gives back horus-gen's bytes exactly: the encoder writes the keys, the
/// order of the types and every value's form as generator/horus_gen/description.py does.
template <class... Ts>
void check_encodes_back(TypeList<Ts...>) {
  const auto check = [](std::string_view type_name, std::string_view carried) {
    SCOPED_TRACE(std::string(type_name));
    const std::string encoded = TypeDescription::decode(carried).encode();
    const auto [at, _] =
        std::mismatch(encoded.begin(), encoded.end(), carried.begin(), carried.end());
    EXPECT_EQ(encoded.size(), carried.size()) << "the encoded description of " << type_name;
    EXPECT_TRUE(at == encoded.end())
        << "the encoded description of " << type_name << " differs from horus-gen's bytes at byte "
        << (at - encoded.begin()) << ", after \""
        << std::string(at - std::min<std::ptrdiff_t>(40, at - encoded.begin()), at) << "\"";
  };
  (check(horus::TypeInfo<Ts>::name, horus::TypeInfo<Ts>::description), ...);
}

TEST(StandardTypeDescriptions, EncodeBackToTheGeneratorsBytes) {
  check_encodes_back(StandardMessages{});
  check_encodes_back(
      TypeList<AudioEncoding, ContactState, GoalStatus, ImageEncoding, TensorDtype>{});
}

template <class E>
void check_standard_enum() {
  using Info = horus::TypeInfo<E>;
  SCOPED_TRACE(std::string(Info::name));
  const TypeDescription description = TypeDescription::decode(Info::description);
  ASSERT_EQ(description.root, Info::name);
  const horus::EnumType* enumeration = description.find_enum(description.root);
  ASSERT_NE(enumeration, nullptr);
  EXPECT_EQ(enumeration->fingerprint, Info::fingerprint);
  EXPECT_EQ(horus::primitive_size(enumeration->underlying), sizeof(E));
  EXPECT_FALSE(enumeration->values.empty());
  for (const horus::Enumerator& enumerator : enumeration->values) {
    EXPECT_EQ(Info::to_string(static_cast<E>(enumerator.value)), enumerator.name);
  }
}

TEST(StandardTypeDescriptions, CarryTheirEnums) {
  check_standard_enum<AudioEncoding>();
  check_standard_enum<ContactState>();
  check_standard_enum<GoalStatus>();
  check_standard_enum<ImageEncoding>();
  check_standard_enum<TensorDtype>();
}

}  // namespace

// ---- build_message: the inverse of walk_message -----------------------------------------------

/// One thing a walk reported: a message or field begun (by name), a value, a sequence's count, an
/// option's presence, or a container's end.
struct WalkStep {
  enum class Kind { Message, Field, End, Bool, Unsigned, Signed, Float, Enum, Text, Bytes, Count };
  Kind kind = Kind::End;
  std::string text;
  std::uint64_t number = 0;
  double floating = 0.0;
};

/// Writes down a walk, step by step.
class WalkRecorder final : public horus::MessageVisitor {
 public:
  std::vector<WalkStep> steps;

  void begin_message(const MessageType& type) override { add(WalkStep::Kind::Message, type.name); }
  void end_message(const MessageType&) override { add(WalkStep::Kind::End); }
  void field(const horus::MessageField& field) override { add(WalkStep::Kind::Field, field.name); }
  void boolean(bool value) override { add(WalkStep::Kind::Bool, {}, value ? 1 : 0); }
  void unsigned_integer(const TypeRef&, std::uint64_t value) override {
    add(WalkStep::Kind::Unsigned, {}, value);
  }
  void signed_integer(const TypeRef&, std::int64_t value) override {
    add(WalkStep::Kind::Signed, {}, static_cast<std::uint64_t>(value));
  }
  void floating(const TypeRef&, double value) override {
    steps.push_back({WalkStep::Kind::Float, {}, 0, value});
  }
  void enumerator(const horus::EnumType&, std::int64_t value) override {
    add(WalkStep::Kind::Enum, {}, static_cast<std::uint64_t>(value));
  }
  void string(const TypeRef&, std::string_view text) override {
    add(WalkStep::Kind::Text, std::string(text));
  }
  void bytes(const TypeRef&, std::span<const std::uint8_t> data) override {
    add(WalkStep::Kind::Bytes, std::string(data.begin(), data.end()));
  }
  void begin_sequence(const TypeRef&, std::size_t count) override {
    add(WalkStep::Kind::Count, {}, count);
  }
  void end_sequence(const TypeRef&) override { add(WalkStep::Kind::End); }
  void begin_optional(const TypeRef&, bool present) override {
    add(WalkStep::Kind::Count, {}, present ? 1 : 0);
  }
  void end_optional(const TypeRef&) override { add(WalkStep::Kind::End); }

 private:
  void add(WalkStep::Kind kind, std::string text = {}, std::uint64_t number = 0) {
    steps.push_back({kind, std::move(text), number, 0.0});
  }
};

/// Answers build_message's questions with a recorded walk's steps, checking that each question
/// is the one the walk reported at that point.
class WalkReplay final : public horus::MessageSource {
 public:
  explicit WalkReplay(std::vector<WalkStep> steps) : steps_(std::move(steps)) {}

  bool replayed_all() const { return next_ == steps_.size(); }

  void begin_message(const MessageType& type) override {
    EXPECT_EQ(take(WalkStep::Kind::Message).text, type.name);
  }
  void end_message(const MessageType&) override { take(WalkStep::Kind::End); }
  void field(const horus::MessageField& field) override {
    EXPECT_EQ(take(WalkStep::Kind::Field).text, field.name);
  }
  bool boolean() override { return take(WalkStep::Kind::Bool).number != 0; }
  std::uint64_t unsigned_integer(const TypeRef&) override {
    return take(WalkStep::Kind::Unsigned).number;
  }
  std::int64_t signed_integer(const TypeRef&) override {
    return static_cast<std::int64_t>(take(WalkStep::Kind::Signed).number);
  }
  double floating(const TypeRef&) override { return take(WalkStep::Kind::Float).floating; }
  std::int64_t enumerator(const horus::EnumType&) override {
    return static_cast<std::int64_t>(take(WalkStep::Kind::Enum).number);
  }
  std::string_view string(const TypeRef&) override { return take(WalkStep::Kind::Text).text; }
  std::span<const std::uint8_t> bytes(const TypeRef&) override {
    const std::string& data = take(WalkStep::Kind::Bytes).text;
    return {reinterpret_cast<const std::uint8_t*>(data.data()), data.size()};
  }
  std::size_t begin_sequence(const TypeRef&) override { return take(WalkStep::Kind::Count).number; }
  void end_sequence(const TypeRef&) override { take(WalkStep::Kind::End); }
  bool begin_optional(const TypeRef&) override { return take(WalkStep::Kind::Count).number != 0; }
  void end_optional(const TypeRef&) override { take(WalkStep::Kind::End); }

 private:
  const WalkStep& take(WalkStep::Kind kind) {
    if (next_ == steps_.size()) throw horus::Error("build_message asked past the recorded walk");
    const WalkStep& step = steps_[next_++];
    if (step.kind != kind) {
      throw horus::Error("build_message asked out of the walk's order at step " +
                         std::to_string(next_ - 1));
    }
    return step;
  }

  std::vector<WalkStep> steps_;
  std::size_t next_ = 0;
};

template <class T>
void check_rebuild(const TypeDescription& description) {
  SCOPED_TRACE(std::string(horus::TypeInfo<T>::name));
  auto value = std::make_unique<T>();
  std::uint64_t k = 1;
  horus_test::fill_every_field(*value, k, horus_test::Enums::Alternate);
  const std::vector<std::uint8_t> encoded = horus::encode(*value);
  WalkRecorder recorder;
  horus::walk_message(description, description.root_message(), encoded, recorder);
  WalkReplay replay(std::move(recorder.steps));
  EXPECT_EQ(horus::build_message(description, description.root_message(), replay), encoded)
      << "a filled " << horus::TypeInfo<T>::name << " built back from its walk differs";
  EXPECT_TRUE(replay.replayed_all()) << "build_message left steps of the walk unasked";
}

template <class... Ts>
void check_rebuilds(TypeList<Ts...>) {
  (check_rebuild<Ts>(TypeDescription::decode(horus::TypeInfo<Ts>::description)), ...);
}

TEST(StandardTypeDescriptions, BuildFilledMessagesBackFromTheirWalks) {
  check_rebuilds(StandardMessages{});
}

TEST(TypeDescription, BuildMessageRefusesAnswersThatDoNotFitTheirType) {
  const TypeDescription description =
      TypeDescription::decode(horus::TypeInfo<horus::msg::ServoCommand>::description);
  const MessageType& servo = description.root_message();
  WalkRecorder recorder;
  const std::vector<std::uint8_t> zero = horus::zero_message(description, servo);
  horus::walk_message(description, servo, zero, recorder);
  // The first unsigned answer (servo_id, a u32) set past what a u32 holds.
  bool widened = false;
  for (WalkStep& step : recorder.steps) {
    if (step.kind == WalkStep::Kind::Unsigned && !widened) {
      step.number = std::uint64_t{1} << 40;
      widened = true;
    }
  }
  ASSERT_TRUE(widened) << "ServoCommand has no unsigned field";
  WalkReplay too_wide(std::move(recorder.steps));
  try {
    horus::build_message(description, servo, too_wide);
    FAIL() << "an unsigned answer of 2^40 was written";
  } catch (const horus::Error& error) {
    EXPECT_STREQ(error.what(),
                 "building a message: field servo_id: 1099511627776 is out of range for u32");
  }
}
