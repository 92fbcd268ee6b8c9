// The C++ side of the plain-value tests (test_runtime_values.py): a Topic of a plain value, in a
// process of its own.
//
//   horus_py_value_peer identity KIND            prints the type's name, fingerprint and schema
//   horus_py_value_peer pub KIND TOPIC           sends KIND's samples, printing for each the hex
//       of its bytes (horus::encode) and its horus::log_summary, tab-separated
//   horus_py_value_peer sub KIND TOPIC COUNT     prints "ready", then the same line for each of
//       COUNT values received
//   horus_py_value_peer hold KIND TOPIC          prints "ready" once the topic is open and keeps
//       it until standard input closes; a refused open prints the error and exits with 1
//
// KIND: f64 (double), i64, i32, bool, string (std::string), bytes (std::vector<std::uint8_t>),
// f32x3 (std::array<float, 3>), vec_f32 (std::vector<float>).
#include <array>
#include <chrono>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <horus/codec.hpp>
#include <horus/error.hpp>
#include <horus/plain_value.hpp>
#include <horus/topic.hpp>

namespace {

using namespace std::chrono_literals;

// The samples each kind sends; test_runtime_values.py holds the same lists.
std::vector<double> samples(double*) { return {0.0, -1.5, 3.141592653589793, 1e300, -0.0}; }
std::vector<std::int64_t> samples(std::int64_t*) {
  return {0, -1, std::numeric_limits<std::int64_t>::max(),
          std::numeric_limits<std::int64_t>::min()};
}
std::vector<std::int32_t> samples(std::int32_t*) { return {7, -7}; }
std::vector<bool> samples(bool*) { return {true, false}; }
std::vector<std::string> samples(std::string*) {
  return {"", "hello", "gr\xc3\xbc\xc3\x9f dich", std::string(40, 'x')};
}
std::vector<std::vector<std::uint8_t>> samples(std::vector<std::uint8_t>*) {
  return {{}, {0x00, 0xff, 0x10}, std::vector<std::uint8_t>(300, 0xab)};
}
std::vector<std::array<float, 3>> samples(std::array<float, 3>*) {
  return {{1.0F, 2.5F, -3.25F}, {0.0F, 0.0F, 0.0F}};
}
std::vector<std::vector<float>> samples(std::vector<float>*) {
  return {{}, {1.0F, 2.5F}, {0.5F, 1.0F, 1.5F, 2.0F, 2.5F, 3.0F, 3.5F, 4.0F, 4.5F}};
}

template <class T>
void print_value(const T& value) {
  for (const std::uint8_t byte : horus::encode(value)) {
    std::printf("%02x", byte);
  }
  std::printf("\t%s\n", horus::log_summary(value).c_str());
  std::fflush(stdout);
}

void ready() {
  std::printf("ready\n");
  std::fflush(stdout);
}

template <class T>
int identity() {
  std::printf("%.*s\n%016" PRIx64 "\n%.*s", static_cast<int>(horus::TypeInfo<T>::name.size()),
              horus::TypeInfo<T>::name.data(), horus::TypeInfo<T>::fingerprint,
              static_cast<int>(horus::TypeInfo<T>::schema.size()),
              horus::TypeInfo<T>::schema.data());
  return 0;
}

template <class T>
int publish(const std::string& topic_name) {
  horus::Topic<T> topic(topic_name);
  for (const T& value : samples(static_cast<T*>(nullptr))) {
    if (!topic.send(value)) {
      std::fprintf(stderr, "send failed\n");
      return 1;
    }
    print_value(value);
  }
  return 0;
}

template <class T>
int subscribe(const std::string& topic_name, int count) {
  horus::Topic<T> topic(topic_name);
  ready();
  for (int i = 0; i < count; ++i) {
    const std::optional<T> value = topic.recv(10s);
    if (!value) {
      std::fprintf(stderr, "timed out after %d values\n", i);
      return 1;
    }
    print_value(*value);
  }
  return 0;
}

template <class T>
int hold(const std::string& topic_name) {
  try {
    horus::Topic<T> topic(topic_name);
    ready();
    std::string line;
    while (std::getline(std::cin, line)) {
    }
    return 0;
  } catch (const horus::Error& error) {
    std::printf("%s\n", error.what());
    return 1;
  }
}

template <class T>
int run(std::string_view role, int argc, char** argv) {
  if (role == "identity") return identity<T>();
  if (argc < 4) return 2;
  const std::string topic = argv[3];
  if (role == "pub") return publish<T>(topic);
  if (role == "hold") return hold<T>(topic);
  if (role == "sub" && argc == 5) return subscribe<T>(topic, std::stoi(argv[4]));
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s identity|pub|sub|hold KIND [TOPIC [COUNT]]\n", argv[0]);
    return 2;
  }
  const std::string_view role = argv[1];
  const std::string_view kind = argv[2];
  if (kind == "f64") return run<double>(role, argc, argv);
  if (kind == "i64") return run<std::int64_t>(role, argc, argv);
  if (kind == "i32") return run<std::int32_t>(role, argc, argv);
  if (kind == "bool") return run<bool>(role, argc, argv);
  if (kind == "string") return run<std::string>(role, argc, argv);
  if (kind == "bytes") return run<std::vector<std::uint8_t>>(role, argc, argv);
  if (kind == "f32x3") return run<std::array<float, 3>>(role, argc, argv);
  if (kind == "vec_f32") return run<std::vector<float>>(role, argc, argv);
  std::fprintf(stderr, "unknown kind %.*s\n", static_cast<int>(kind.size()), kind.data());
  return 2;
}
