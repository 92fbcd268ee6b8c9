// The framework clock: fixed dt and simulated time in deterministic mode, reproducible random
// sequences, and the values outside any callback.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "horus/clock.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

struct Sample {
  std::int64_t now_ns;
  std::int64_t dt_ns;
  std::uint64_t tick;
  bool operator==(const Sample&) const = default;
};

class ClockProbe : public horus::Node {
 public:
  explicit ClockProbe(std::string name) : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    samples.push_back({horus::now().count(), horus::dt().count(), horus::tick_index()});
  }
  std::vector<Sample> samples;

 private:
  std::string name_;
};

// A noisy 1-D vehicle: position integrates velocity; velocity gets random kicks.
class NoisyVehicle : public horus::Node {
 public:
  std::string_view name() const override { return "vehicle"; }
  void tick() override {
    const double dt = std::chrono::duration<double>(horus::dt()).count();
    velocity_ += (horus::rng_float() - 0.5) * 2.0 * dt;
    position_ += velocity_ * dt;
    trajectory.push_back(position_);
  }
  std::vector<double> trajectory;

 private:
  double velocity_ = 1.0;
  double position_ = 0.0;
};

class Observer : public horus::Node {
 public:
  explicit Observer(const NoisyVehicle& v) : vehicle_(v) {}
  std::string_view name() const override { return "observer"; }
  void tick() override {
    const double noise = horus::rng_float();
    seen.push_back(vehicle_.trajectory.empty() ? noise : vehicle_.trajectory.back() + noise);
  }
  std::vector<double> seen;

 private:
  const NoisyVehicle& vehicle_;
};

std::pair<std::vector<double>, std::vector<double>> simulate(std::uint64_t seed) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).deterministic(true).seed(seed)};
  auto vehicle = std::make_unique<NoisyVehicle>();
  auto observer = std::make_unique<Observer>(*vehicle);
  NoisyVehicle* v = vehicle.get();
  Observer* o = observer.get();
  sched.add(std::move(observer)).order(1).rate(50_hz).build();
  sched.add(std::move(vehicle)).order(0).rate(100_hz).build();
  sched.run_for(2_s);
  return {v->trajectory, o->seen};
}

}  // namespace

TEST(ClockDeterministic, DtIsFixedAndTimeIsSimulated) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).deterministic(true)};
  auto fast = std::make_unique<ClockProbe>("fast");
  auto slow = std::make_unique<ClockProbe>("slow");
  ClockProbe* f = fast.get();
  ClockProbe* s = slow.get();
  sched.add(std::move(fast)).build();
  sched.add(std::move(slow)).rate(10_hz).build();
  for (int i = 0; i < 1000; ++i) sched.tick_once();
  ASSERT_EQ(f->samples.size(), 1000U);
  ASSERT_EQ(s->samples.size(), 100U);
  for (std::size_t i = 0; i < f->samples.size(); ++i) {
    EXPECT_EQ(f->samples[i], (Sample{static_cast<std::int64_t>(i) * 10'000'000, 10'000'000, i}));
  }
  for (std::size_t i = 0; i < s->samples.size(); ++i) {
    EXPECT_EQ(s->samples[i], (Sample{static_cast<std::int64_t>(i) * 100'000'000, 100'000'000, i}));
  }
}

TEST(ClockDeterministic, SameSeedSameOutputsEveryRun) {
  const auto first = simulate(7);
  const auto second = simulate(7);
  ASSERT_EQ(first.first.size(), 200U);
  ASSERT_EQ(first.second.size(), 100U);
  EXPECT_EQ(first.first, second.first);
  EXPECT_EQ(first.second, second.second);
  const auto other = simulate(8);
  EXPECT_NE(first.first, other.first) << "the seed must matter";
}

TEST(ClockDeterministic, RandomNumbersAreInUnitInterval) {
  for (int i = 0; i < 10000; ++i) {
    const double x = horus::rng_float();
    ASSERT_GE(x, 0.0);
    ASSERT_LT(x, 1.0);
  }
}

TEST(ClockDeterministic, OutsideACallbackThereIsNoTick) {
  EXPECT_EQ(horus::dt(), 0_ms);
  EXPECT_EQ(horus::elapsed(), 0_ms);
  EXPECT_EQ(horus::tick_index(), 0U);
  EXPECT_EQ(horus::budget_remaining(), std::chrono::nanoseconds::max());
  EXPECT_EQ(horus::lateness(), 0_ms);
  // Wall clock: after 2020-01-01.
  EXPECT_GT(horus::now(), std::chrono::seconds(1'577'836'800));
}

TEST(ClockDeterministic, RealModeDtFollowsTheWallClock) {
  horus::Scheduler sched;
  auto probe = std::make_unique<ClockProbe>("probe");
  ClockProbe* p = probe.get();
  sched.add(std::move(probe)).rate(100_hz).build();
  sched.tick_once();
  std::this_thread::sleep_for(5_ms);
  sched.tick_once();
  ASSERT_EQ(p->samples.size(), 2U);
  EXPECT_EQ(p->samples[0].dt_ns, 10'000'000) << "first tick: the nominal period";
  EXPECT_GE(p->samples[1].dt_ns, 5'000'000) << "second tick: at least the sleep in between";
  EXPECT_EQ(p->samples[1].tick, 1U);
}

namespace with_horus_names {
using namespace horus;  // NOLINT(google-build-using-namespace): what the rename is for

// Inside a node, Node::tick() hides a free function of the same name; tick_index() is not hidden.
class CountsItsTicks : public Node {
 public:
  void tick() override { seen.push_back(tick_index()); }
  std::vector<std::uint64_t> seen;
};

}  // namespace with_horus_names

TEST(Clock, TickIndexIsReachableUnqualifiedInsideANode) {
  auto node = std::make_shared<with_horus_names::CountsItsTicks>();
  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true)};
  sched.add(node).build();
  for (int i = 0; i < 3; ++i) sched.tick_once();
  EXPECT_EQ(node->seen, (std::vector<std::uint64_t>{0, 1, 2}));
}
