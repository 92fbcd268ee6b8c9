// Deterministic mode runs a subscriber after its publishers within a pass, whatever order() says;
// order() breaks ties and cycles, and a cycle is reported once.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "horus/log.hpp"
#include "horus/scheduler.hpp"

namespace {

class Wired : public horus::Node {
 public:
  Wired(std::string name, std::vector<std::string> pubs, std::vector<std::string> subs,
        std::string& trace)
      : name_(std::move(name)), pubs_(std::move(pubs)), subs_(std::move(subs)), trace_(trace) {}
  std::string_view name() const override { return name_; }
  void tick() override { trace_ += name_ + " "; }
  std::vector<horus::TopicMetadata> publishers() const override { return metadata(pubs_); }
  std::vector<horus::TopicMetadata> subscribers() const override { return metadata(subs_); }

 private:
  static std::vector<horus::TopicMetadata> metadata(const std::vector<std::string>& topics) {
    std::vector<horus::TopicMetadata> out;
    for (const auto& t : topics) out.push_back({t, "horus.msg.Dummy"});
    return out;
  }
  std::string name_;
  std::vector<std::string> pubs_;
  std::vector<std::string> subs_;
  std::string& trace_;
};

struct Spec {
  std::string name;
  int order;
  std::vector<std::string> pubs;
  std::vector<std::string> subs;
};

std::string one_pass(const std::vector<Spec>& specs, bool deterministic = true) {
  std::string trace;
  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(deterministic).name("graph")};
  for (const Spec& s : specs) {
    sched.add(std::make_shared<Wired>(s.name, s.pubs, s.subs, trace)).order(s.order).build();
  }
  sched.tick_once();
  return trace;
}

}  // namespace

TEST(TopicOrder, ASubscriberTicksAfterItsPublisherDespiteALowerOrder) {
  const std::vector<Spec> specs = {{"motor", 0, {}, {"cmd"}}, {"planner", 10, {"cmd"}, {}}};
  EXPECT_EQ(one_pass(specs), "planner motor ");
  EXPECT_EQ(one_pass(specs, false), "motor planner ");  // outside deterministic mode: order()
}

TEST(TopicOrder, AChainRunsFromSourceToSink) {
  EXPECT_EQ(one_pass({{"sink", 100, {}, {"b"}},
                      {"middle", 100, {"b"}, {"a"}},
                      {"source", 100, {"a"}, {}}}),
            "source middle sink ");
}

TEST(TopicOrder, OrderBreaksTiesBetweenIndependentNodes) {
  EXPECT_EQ(one_pass({{"late", 50, {"x"}, {}}, {"early", 5, {"y"}, {}}, {"reader", 1, {}, {"x"}}}),
            "early late reader ");
}

TEST(TopicOrder, ACycleIsBrokenByOrderAndANodeBehindItWaitsOnlyForItsPublisher) {
  // a <-> b form a cycle, broken at a (lower order); c (lowest order) reads a only.
  EXPECT_EQ(one_pass({{"c", 0, {}, {"from_a"}},
                      {"b", 2, {"from_b"}, {"from_a"}},
                      {"a", 1, {"from_a"}, {"from_b"}}}),
            "a c b ");
}

TEST(TopicOrder, ACycleIsReportedOnce) {
  std::string trace;
  testing::internal::CaptureStderr();
  {
    horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true).name("graph")};
    sched.add(std::make_shared<Wired>("a", std::vector<std::string>{"x"},
                                      std::vector<std::string>{"y"}, trace))
        .build();
    sched.add(std::make_shared<Wired>("b", std::vector<std::string>{"y"},
                                      std::vector<std::string>{"x"}, trace))
        .build();
    for (int i = 0; i < 3; ++i) sched.tick_once();
    sched.add(std::make_shared<Wired>("c", std::vector<std::string>{}, std::vector<std::string>{},
                                      trace))
        .build();  // the order is computed again; the cycle is not reported again
    sched.tick_once();
  }
  horus::log::flush();
  const std::string err = testing::internal::GetCapturedStderr();
  const std::string line = "WARN @graph: topic cycle: 'a' run before their publishers (by order())";
  const auto first = err.find(line);
  ASSERT_NE(first, std::string::npos) << err;
  EXPECT_EQ(err.find(line, first + 1), std::string::npos) << err;
  EXPECT_EQ(trace, "a b a b a b c a b ");  // c, waiting for nobody, is ready before the cycle
}
