// The C++ half of the cross-language tests (tests/python/test_python_crosslang.py): one fixed,
// non-trivial value of every type in tests/schemas, written as wire bytes for Python to read, and
// the checker of what Python wrote for the same values.
//
//   horus_crosslang write DIR   DIR/<type>.bin (horus::encode), DIR/<type>.txt (log_summary),
//                               DIR/fingerprints.txt (every message, enum and service)
//   horus_crosslang check DIR   decodes each DIR/<type>.bin that Python wrote and compares it field
//                               by field with the same value, then the summaries and fingerprints;
//                               exit status 1 and one line per difference when anything differs.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <horus/codec.hpp>
#include <horus/log_summary.hpp>
#include <horus/msgpack.hpp>
#include <other_pkg.hpp>
#include <test_msgs.hpp>

namespace {

using namespace test_msgs;
namespace fs = std::filesystem;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

template <class T>
T fixture();

template <>
Point2 fixture<Point2>() {
  return {.x = 1.5, .y = -2.25};
}

template <>
Pose2 fixture<Pose2>() {
  return {.position = {.x = 3.0, .y = 4.0}, .theta = 0.1F};
}

template <>
other_pkg::Stamp fixture<other_pkg::Stamp>() {
  // 301 is not an enumerator: both languages keep the number and print it.
  return {.sec = 1700000000, .nanosec = 5, .source = static_cast<other_pkg::Source>(301)};
}

template <>
Primitives fixture<Primitives>() {
  return {.flag = true,
          .u64_value = std::numeric_limits<std::uint64_t>::max(),
          .u8_value = 255,
          .u16_value = 65535,
          .i8_value = -128,
          .u32_value = 4294967295U,
          .i16_value = -32768,
          .i32_value = std::numeric_limits<std::int32_t>::min(),
          .i64_value = std::numeric_limits<std::int64_t>::min(),
          .f32_value = 1e20F,
          .f64_value = -0.0};
}

template <>
Arrays fixture<Arrays>() {
  Arrays a{};
  a.small = {1, 65535, 300};
  for (std::size_t i = 0; i < a.ranges.size(); ++i)
    a.ranges[i] = 0.25F * static_cast<float>(i) - 10.0F;
  a.grid = {{{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 255}}};
  a.name = "twelve bytes";
  a.names[0] = "eight ch";
  a.names[1] = "x";
  a.poses[0] = {.position = {.x = 1.0, .y = 2.0}, .theta = 0.5F};
  a.poses[1] = {.position = {.x = -1.0, .y = -2.0}, .theta = -0.5F};
  a.flags = {true, false, true, true, false};
  return a;
}

template <>
Defaults fixture<Defaults>() {
  Defaults d{};
  d.speed = 1.5F;
  d.count = 4000000001U;
  d.offset = -30000;
  d.mode = Mode::Fault;
  d.enabled = false;
  d.label = "ab";
  d.gains = {0.1, 0.2, 0.3};
  d.stamp = {.sec = -7, .nanosec = 999999999, .source = other_pkg::Source::Ptp};
  return d;
}

template <>
Empty fixture<Empty>() {
  return {};
}

template <>
ImuLike fixture<ImuLike>() {
  ImuLike m{};
  m.orientation = {0.0, 0.0, 0.7071067811865476, 0.7071067811865476};
  for (std::size_t i = 0; i < 9; ++i) {
    m.orientation_covariance[i] = 0.01 * static_cast<double>(i);
    m.angular_velocity_covariance[i] = -0.5 * static_cast<double>(i);
    m.linear_acceleration_covariance[i] = 1e-9 * static_cast<double>(i + 1);
  }
  m.angular_velocity = {0.1, -0.2, 0.3};
  m.linear_acceleration = {0.0, 0.0, 9.81};
  m.timestamp_ns = 1700000000123456789ULL;
  return m;
}

template <>
Serialized fixture<Serialized>() {
  Serialized s{};
  s.text = "h\xc3\xa9llo w\xc3\xb6rld \xe2\x9c\x93";
  for (int i = 0; i < 300; ++i) s.data.push_back(static_cast<std::uint8_t>(i * 7));
  // Integral doubles are packed as integers by msgpack-cxx, the rest as float64: every branch once.
  s.values = {0.0,
              -0.0,
              1.5,
              3.0,
              1e20,
              -1e20,
              kNan,
              kInf,
              -kInf,
              18446744073709551616.0,
              -9223372036854775808.0,
              1234565.0,
              1e-7,
              -2.5,
              9007199254740993.0};
  s.counts = {0, 127, 128, 255, 256, 65535, 65536, 4294967295U};
  s.small = {1, 2, 3};
  s.maybe = -33;
  s.maybe_text = "opt";
  s.poses = {{.position = {.x = 1.25, .y = -0.0}, .theta = 3.0F},
             {.position = {.x = 1e20, .y = -7.0}, .theta = 1e-3F}};
  s.tags = {"a", std::string(40, 'x'), ""};
  s.fixed = {0.5F, -1.0F, 1e-3F};
  s.mode = Mode::Fault;
  s.label = "sixteen-bytes-ok";
  s.nested = std::vector<Point2>{{.x = 1.0, .y = 2.0}, {.x = -3.5, .y = 4.0}};
  return s;
}

template <>
Blob fixture<Blob>() {
  Blob b{};
  b.seq = std::numeric_limits<std::uint64_t>::max();
  b.payload.resize(70000);
  for (std::size_t i = 0; i < b.payload.size(); ++i)
    b.payload[i] = static_cast<std::uint8_t>((i * 7) & 0xFF);
  return b;
}

template <>
GetRobotPoseRequest fixture<GetRobotPoseRequest>() {
  return {.robot_name = "robot-7"};
}

template <>
GetRobotPoseResponse fixture<GetRobotPoseResponse>() {
  return {.x = 1.0, .y = 2.0, .theta = -3.14159, .timestamp_ns = 42};
}

template <>
AddIntsRequest fixture<AddIntsRequest>() {
  return {.a = -5, .b = std::numeric_limits<std::int64_t>::max()};
}

template <>
AddIntsResponse fixture<AddIntsResponse>() {
  return {.sum = 9223372036854775802LL};
}

// -- field-by-field comparison, NaN equal to NaN -----------------------------------------------

using Diffs = std::vector<std::string>;

template <class T>
void compare(const std::string& path, const T& a, const T& b, Diffs& diffs);

template <class T>
void compare_message(const std::string& path, const T& a, const T& b, Diffs& diffs) {
  std::vector<const void*> theirs;
  horus::TypeInfo<T>::visit(b,
                            [&](std::string_view, const auto& field) { theirs.push_back(&field); });
  std::size_t index = 0;
  horus::TypeInfo<T>::visit(a, [&](std::string_view name, const auto& field) {
    using Field = std::remove_cvref_t<decltype(field)>;
    compare(path + "." + std::string(name), field, *static_cast<const Field*>(theirs[index++]),
            diffs);
  });
}

template <class T>
std::string text_of(const T& value) {
  std::string out;
  horus::summary::append_value(out, value);
  return out;
}

template <class T>
void compare(const std::string& path, const T& a, const T& b, Diffs& diffs) {
  if constexpr (horus::Message<T>) {
    compare_message(path, a, b, diffs);
  } else if constexpr (std::is_floating_point_v<T>) {
    if (!(a == b || (std::isnan(a) && std::isnan(b))))
      diffs.push_back(path + ": " + text_of(a) + " != " + text_of(b));
  } else if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
    if (a != b) diffs.push_back(path + ": " + text_of(a) + " != " + text_of(b));
  } else if constexpr (std::is_convertible_v<const T&, std::string_view>) {
    if (std::string_view(a) != std::string_view(b))
      diffs.push_back(path + ": " + text_of(a) + " != " + text_of(b));
  } else if constexpr (horus::summary::OptionalLike<T>) {
    if (a.has_value() != b.has_value()) {
      diffs.push_back(path + ": " + text_of(a) + " != " + text_of(b));
    } else if (a.has_value()) {
      compare(path, *a, *b, diffs);
    }
  } else {
    if (a.size() != b.size()) {
      diffs.push_back(path + ": " + std::to_string(a.size()) +
                      " elements != " + std::to_string(b.size()));
      return;
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      using Element = std::remove_cvref_t<decltype(a[i])>;
      const Element ea = a[i], eb = b[i];
      compare(path + "[" + std::to_string(i) + "]", ea, eb, diffs);
    }
  }
}

// -- files ----------------------------------------------------------------------------------------

std::optional<std::string> read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_file(const fs::path& path, std::string_view content) {
  std::ofstream out(path, std::ios::binary);
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  if (!out) throw horus::Error("cannot write " + path.string());
}

template <class T>
std::string fingerprint_line() {
  char hex[32];
  std::snprintf(hex, sizeof hex, "0x%016llx",
                static_cast<unsigned long long>(horus::TypeInfo<T>::fingerprint));
  return std::string(horus::TypeInfo<T>::name) + " " + hex + "\n";
}

template <class S>
std::string service_line() {
  char hex[32];
  std::snprintf(hex, sizeof hex, "0x%016llx", static_cast<unsigned long long>(S::fingerprint()));
  return "test_msgs." + std::string(S::name()) + " " + hex + "\n";
}

template <class... Ts>
struct TypeList {};

using Messages = TypeList<Point2, Pose2, other_pkg::Stamp, Primitives, Arrays, Defaults, Empty,
                          ImuLike, Serialized, Blob, GetRobotPoseRequest, GetRobotPoseResponse,
                          AddIntsRequest, AddIntsResponse>;

std::string fingerprints() {
  std::string out;
  [&]<class... Ts>(TypeList<Ts...>) { ((out += fingerprint_line<Ts>()), ...); }(Messages{});
  out += fingerprint_line<Mode>();
  out += fingerprint_line<other_pkg::Source>();
  out += service_line<GetRobotPose>();
  out += service_line<AddInts>();
  return out;
}

template <class T>
void write_one(const fs::path& dir) {
  const T value = fixture<T>();
  const std::vector<std::uint8_t> bytes = horus::encode(value);
  const std::string name(horus::TypeInfo<T>::name);
  write_file(dir / (name + ".bin"),
             std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  write_file(dir / (name + ".txt"), value.log_summary());
}

template <class T>
void check_one(const fs::path& dir, Diffs& diffs) {
  const std::string name(horus::TypeInfo<T>::name);
  const T expected = fixture<T>();
  const std::optional<std::string> data = read_file(dir / (name + ".bin"));
  if (!data) {
    diffs.push_back(name + ": " + (dir / (name + ".bin")).string() + " is missing");
    return;
  }
  const auto* begin = reinterpret_cast<const std::uint8_t*>(data->data());
  try {
    const T got = horus::decode<T>(std::span<const std::uint8_t>(begin, data->size()));
    compare(name, got, expected, diffs);
  } catch (const horus::DecodeError& error) {
    diffs.push_back(name + ": C++ cannot decode Python's bytes: " + error.what());
  }
  const std::optional<std::string> summary = read_file(dir / (name + ".txt"));
  if (!summary || *summary != expected.log_summary()) {
    diffs.push_back(name + ": log_summary differs:\n  C++:    " + expected.log_summary() +
                    "\n  Python: " + summary.value_or("(missing)"));
  }
}

int run(std::string_view command, const fs::path& dir) {
  if (command == "write") {
    fs::create_directories(dir);
    [&]<class... Ts>(TypeList<Ts...>) { (write_one<Ts>(dir), ...); }(Messages{});
    write_file(dir / "fingerprints.txt", fingerprints());
    return 0;
  }
  if (command == "check") {
    Diffs diffs;
    [&]<class... Ts>(TypeList<Ts...>) { (check_one<Ts>(dir, diffs), ...); }(Messages{});
    const std::optional<std::string> theirs = read_file(dir / "fingerprints.txt");
    if (!theirs || *theirs != fingerprints()) {
      diffs.push_back("fingerprints differ:\nC++:\n" + fingerprints() + "Python:\n" +
                      theirs.value_or("(missing)"));
    }
    for (const std::string& diff : diffs) std::fprintf(stderr, "%s\n", diff.c_str());
    if (diffs.empty()) {
      const std::size_t count = []<class... Ts>(TypeList<Ts...>) {
        return sizeof...(Ts);
      }(Messages{});
      std::printf("all %zu types equal\n", count);
    }
    return diffs.empty() ? 0 : 1;
  }
  std::fprintf(stderr, "usage: horus_crosslang write|check DIR\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) return run("", {});
  try {
    return run(argv[1], argv[2]);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "horus_crosslang: %s\n", error.what());
    return 1;
  }
}
