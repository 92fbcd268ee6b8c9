// A node with one parameter of each kind, MessagePack values, and waiting helpers for the
// parameter tests.
#pragma once

#include <msgpack.hpp>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>

#include "horus/node.hpp"
#include "horus/params.hpp"
#include "private_shm_root.hpp"

namespace horus_test {

/// Whether the node's store exists and its owner runs.
inline bool store_owned(const std::string& node) {
  try {
    return horus::ParamStoreReader(node).owner_alive();
  } catch (const horus::Error&) {
    return false;
  }
}

/// A private shared-memory root for the test process, which its children (HORUS_TEST_ROLE set)
/// share rather than make their own.
inline const char* shared_root(const char* namespace_name) {
  if (std::getenv("HORUS_TEST_ROLE") == nullptr) {
    static const PrivateShmRoot root(namespace_name);
    return root.root().c_str();
  }
  return std::getenv("HORUS_SHM_DIR");
}

/// MessagePack VALUE bytes of a plain value.
template <class T>
std::string packed(const T& value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  if constexpr (std::is_same_v<T, double>) {
    packer.pack_double(value);
  } else {
    packer.pack(value);
  }
  return std::string(buffer.data(), buffer.size());
}

inline std::string packed_list(const std::array<double, 3>& values) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack_array(3);
  for (const double value : values) packer.pack_double(value);
  return std::string(buffer.data(), buffer.size());
}

/// A MessagePack VALUE as a double (numbers) or text (strings), for assertions.
inline double number_of(const std::string& value) {
  const msgpack::object_handle handle = msgpack::unpack(value.data(), value.size());
  return handle.get().as<double>();
}
inline std::string text_of(const std::string& value) {
  const msgpack::object_handle handle = msgpack::unpack(value.data(), value.size());
  return handle.get().as<std::string>();
}

class Motor : public horus::Node {
 public:
  explicit Motor(std::string name = "motor") : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    enter();
    ++plain_ticks;
    if (tick_sleep.count() > 0) std::this_thread::sleep_for(tick_sleep);
    ticks.fetch_add(1);
    leave();
  }
  horus::ParamVerdict on_param_change(const horus::ParamChange& change) override {
    enter();
    // Unsynchronised state shared with tick(): the scheduler's ordering alone makes this safe
    // (ThreadSanitizer checks it in the sanitizer build).
    ticks_seen_by_changes = plain_ticks;
    {
      std::lock_guard lock(mutex);
      last_source = change.source;
    }
    changes.fetch_add(1);
    leave();
    if (change.name() == "max_speed" && change.as<double>() == 1.25) {
      return horus::ParamVerdict::refuse("1.25 is not a speed this motor likes");
    }
    return horus::ParamVerdict::accept();
  }

  std::string name_;
  horus::Param<double> max_speed = declare_param<double>(
      "max_speed", 1.0, {.min = 0.0, .max = 2.0, .unit = "m/s", .doc = "Top speed."});
  horus::Param<std::string> profile =
      declare_param<std::string>("profile", "eco", {.choices = {"eco", "sport"}});
  horus::Param<std::int32_t> retries = declare_param<std::int32_t>("retries", 3);
  horus::Param<std::array<double, 3>> gains =
      declare_param<std::array<double, 3>>("gains", {1.0, 0.5, 0.0});
  horus::Param<std::uint8_t> wheel_count =
      declare_param<std::uint8_t>("wheel_count", 4, {.read_only = true});
  horus::Param<std::string> label = declare_param<std::string>("label", "");
  horus::Param<bool> enabled = declare_param<bool>("enabled", true);

  std::atomic<int> ticks{0};
  std::atomic<int> changes{0};
  /// How long each tick takes (a change that arrives during one must wait for its end).
  std::chrono::microseconds tick_sleep{0};
  /// Times tick() and on_param_change() overlapped (the scheduler promises never).
  std::atomic<int> overlaps{0};
  int plain_ticks = 0;
  int ticks_seen_by_changes = 0;
  std::mutex mutex;
  std::string last_source;

 private:
  void enter() {
    if (inside_.exchange(true)) overlaps.fetch_add(1);
  }
  void leave() { inside_.store(false); }
  std::atomic<bool> inside_{false};
};

/// Waits until `done()` or `timeout`; whether it came true.
template <class Condition>
bool eventually(Condition done, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

}  // namespace horus_test
