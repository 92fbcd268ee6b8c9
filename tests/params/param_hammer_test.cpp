// Readers hammering a string and an array parameter (through the store, as other processes
// read, and through the node's own handles) while a writer changes them: every value read is one
// that was written, whole. Labelled `transport`: scripts/test reruns it under ThreadSanitizer.
#include <gtest/gtest.h>

#include <thread>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "param_test_support.hpp"

using namespace horus::literals;
using horus_test::Motor;
using horus_test::packed;
using horus_test::packed_list;

namespace {

const std::string shm_root = horus_test::shared_root("param_hammer");

std::string text_for(std::uint64_t n) {
  return "v" + std::to_string(n) + std::string(20 + n % 200, static_cast<char>('a' + n % 26));
}

bool is_written_text(const std::string& text) {
  if (text.empty()) return true;  // the default
  if (text[0] != 'v') return false;
  const std::size_t digits = text.find_first_not_of("0123456789", 1);
  if (digits == 1 || digits == std::string::npos) return false;
  return text == text_for(std::stoull(text.substr(1, digits - 1)));
}

bool is_written_gains(const std::array<double, 3>& gains) {
  return (gains == std::array<double, 3>{1.0, 0.5, 0.0}) ||
         (gains[1] == gains[0] * 2 && gains[2] == gains[0] * 3);
}

}  // namespace

TEST(ParamHammer, ReadersSeeOnlyValuesThatWereWritten) {
  auto motor = std::make_shared<Motor>();
  horus::Scheduler scheduler(horus::SchedulerConfig{}.tick_rate(500_hz).handle_signals(false));
  scheduler.add(motor).rate(500_hz).build();
  std::thread runner([&] { scheduler.run(); });
  if (!horus_test::eventually([] { return horus_test::store_owned("motor"); })) {
    scheduler.stop();
    runner.join();
    FAIL() << "the store never opened";
  }
  std::atomic<bool> running{true};
  std::atomic<int> bad{0};
  std::atomic<std::uint64_t> reads{0};
  std::vector<std::thread> readers;
  readers.emplace_back([&] {  // as another process reads
    const horus::ParamStoreReader store("motor");
    while (running.load()) {
      const std::string text_value = store.get("label").value;
      const msgpack::object_handle text = msgpack::unpack(text_value.data(), text_value.size());
      const std::string gains_value = store.get("gains").value;
      const msgpack::object_handle gains = msgpack::unpack(gains_value.data(), gains_value.size());
      if (!is_written_text(text.get().as<std::string>()) ||
          !is_written_gains(gains.get().as<std::array<double, 3>>())) {
        bad.fetch_add(1);
      }
      reads.fetch_add(1);
    }
  });
  readers.emplace_back([&] {  // the node's own handles
    while (running.load()) {
      if (!is_written_text(motor->label.get()) || !is_written_gains(motor->gains.get())) {
        bad.fetch_add(1);
      }
      reads.fetch_add(1);
    }
  });
  std::uint64_t writes = 0;
  const auto stop = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  for (std::uint64_t n = 1; std::chrono::steady_clock::now() < stop; ++n) {
    const double g = static_cast<double>(n);
    const bool accepted =
        horus::set_param("motor", "label", packed(text_for(n))).accepted &&
        horus::set_param("motor", "gains", packed_list({g, g * 2, g * 3})).accepted;
    EXPECT_TRUE(accepted);
    if (!accepted) break;
    writes += 2;
  }
  running = false;
  for (std::thread& reader : readers) reader.join();
  scheduler.stop();
  runner.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_GT(writes, 20U);
  EXPECT_GT(reads.load(), writes);
  EXPECT_EQ(motor->changes.load(), static_cast<int>(writes));
}
