// Builds the example's generated messages, prints their log lines and layouts, and checks that
// each comes back unchanged from its wire bytes. Exits non-zero if one does not.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string_view>
#include <vector>

#include <demo_robot/msg.hpp>
#include <horus/codec.hpp>
#include <horus/msgpack.hpp>  // encodes MotorStatus, a serialized (MessagePack) message

namespace {

struct Slot {
  std::size_t offset;
  std::size_t size;
  std::string_view name;
};

// Identity, then where each field sits: the bytes a C++ and a Python process share.
template <horus::Message T>
void print_layout(const T& msg) {
  using Info = horus::TypeInfo<T>;
  std::printf("%.*s  fingerprint %016llx  ", static_cast<int>(Info::name.size()), Info::name.data(),
              static_cast<unsigned long long>(Info::fingerprint));
  if constexpr (Info::is_pod) {
    std::printf("POD, %zu bytes, align %zu\n  offset   size  field\n", Info::size, Info::alignment);
    std::vector<Slot> slots;
    const auto* base = reinterpret_cast<const std::byte*>(&msg);
    Info::visit(msg, [&](std::string_view field, const auto& value) {
      const auto offset = reinterpret_cast<const std::byte*>(&value) - base;
      slots.push_back({static_cast<std::size_t>(offset), sizeof value, field});
    });
    for (const horus::PaddingRange& hole : Info::padding) {
      slots.push_back({hole.offset, hole.size, "(padding)"});
    }
    std::sort(slots.begin(), slots.end(),
              [](const Slot& a, const Slot& b) { return a.offset < b.offset; });
    for (const Slot& slot : slots) {
      std::printf("  %6zu %6zu  %.*s\n", slot.offset, slot.size, static_cast<int>(slot.name.size()),
                  slot.name.data());
    }
  } else {
    std::printf("serialized (MessagePack), fields:");
    Info::visit(msg, [](std::string_view field, const auto&) {
      std::printf(" %.*s", static_cast<int>(field.size()), field.data());
    });
    std::printf("\n");
  }
}

template <horus::Message T>
bool show(const T& msg) {
  print_layout(msg);
  std::printf("  %s\n", msg.log_summary().c_str());
  const std::vector<std::uint8_t> bytes = horus::encode(msg);
  const bool same = horus::decode<T>(bytes) == msg;
  std::printf("  %zu wire bytes, decoded %s\n\n", bytes.size(), same ? "unchanged" : "DIFFERENT");
  return same;
}

}  // namespace

int main() {
  using namespace demo_robot::msg;

  Pose2D pose{};
  pose.x = 1.25;
  pose.y = -0.5;
  pose.theta = 0.785;

  MotorFeedback feedback{};
  feedback.timestamp_ns = 1'700'000'000'000'000'000;
  feedback.motor_id = 2;
  feedback.mode = ControlMode::Torque;
  feedback.velocity = 12.5F;
  feedback.pose = pose;
  for (std::size_t i = 0; i < feedback.phase_currents.size(); ++i) {
    feedback.phase_currents[i] = 0.25F * static_cast<float>(i);
  }
  feedback.frame_id = "left_front";

  MotorStatus status{};
  status.motor_id = 2;
  status.message = "overcurrent on phase B, recovered";
  status.fault_codes = {17, 42};
  status.last_fault_ns = feedback.timestamp_ns - 5'000'000;

  bool ok = show(pose);
  ok = show(feedback) && ok;
  ok = show(status) && ok;
  return ok ? 0 : 1;
}
