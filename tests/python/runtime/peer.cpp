// The C++ side of the Python runtime's cross-process tests: publishes or subscribes to a CmdVel
// (POD), a CompressedImage (serialized) or a GenericMessage holding {"linear": x} (a Python dict).
// The `horus` command's suite (tests/cli) runs its `node` role as a live C++ scheduler.
//
//   horus_py_peer pub  cmdvel|image|dict TOPIC COUNT   sends COUNT messages, value i = 1..COUNT
//   horus_py_peer sub  cmdvel|image|dict TOPIC COUNT   prints "ready", then one value per message
//   horus_py_peer node cmdvel|image|dict TOPIC HZ      a scheduler's node "cpp_talker" sends
//       value i = 1, 2, ... at HZ and logs "sent i" (HORUS_LOG_INFO) every tenth message; prints
//       "ready" after its first message and runs until its standard input closes
//   horus_py_peer session cmdvel|image|dict TOPIC COUNT  a Scheduler with recording(true) whose
//       C++ nodes publish (value i = 1..COUNT, one a tick, 1 ms apart) and subscribe to TOPIC;
//       prints the session file stop_recording() returns (tests/recording)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <horus/log.hpp>
#include <horus/msg.hpp>
#include <horus/node.hpp>
#include <horus/scheduler.hpp>
#include <horus/topic.hpp>

namespace {

using namespace std::chrono_literals;
using horus::msg::CmdVel;
using horus::msg::CompressedImage;
using horus::msg::GenericMessage;

double value_of(const CmdVel& msg) { return msg.linear; }
double value_of(const CompressedImage& msg) { return msg.width; }
double value_of(const GenericMessage& msg) {
  return msg.to_value<std::map<std::string, double>>().at("linear");
}

CmdVel make(CmdVel*, int i) {
  CmdVel msg{};
  msg.linear = static_cast<float>(i);
  msg.angular = -static_cast<float>(i);
  return msg;
}
CompressedImage make(CompressedImage*, int i) {
  CompressedImage msg{};
  msg.format = "png";
  msg.width = static_cast<std::uint32_t>(i);
  msg.height = 2;
  msg.data = std::vector<std::uint8_t>(static_cast<std::size_t>(i), 0xab);
  return msg;
}
GenericMessage make(GenericMessage*, int i) {
  return GenericMessage::from_value(std::map<std::string, double>{{"linear", double(i)}});
}

template <class T>
int publish(const std::string& topic_name, int count) {
  horus::Topic<T> topic(topic_name);
  for (int i = 1; i <= count; ++i) {
    if (!topic.send(make(static_cast<T*>(nullptr), i))) {
      std::fprintf(stderr, "send %d failed\n", i);
      return 1;
    }
    std::this_thread::sleep_for(2ms);
  }
  return 0;
}

template <class T>
int subscribe(const std::string& topic_name, int count) {
  horus::Topic<T> topic(topic_name);
  std::printf("ready\n");
  std::fflush(stdout);
  for (int i = 0; i < count; ++i) {
    auto msg = topic.recv(10s);
    if (!msg) {
      std::fprintf(stderr, "timed out after %d messages\n", i);
      return 1;
    }
    std::printf("%g\n", value_of(*msg));
    std::fflush(stdout);
  }
  return 0;
}

/// Publishes make(i) on its topic at tick i (1..count), then nothing.
template <class T>
class Driver : public horus::Node {
 public:
  Driver(std::string topic, int count)
      : topic_name_(std::move(topic)), out_(topic_name_), count_(count) {}
  std::string_view name() const override { return "cpp_driver"; }
  void tick() override {
    if (next_ <= count_) out_.send(make(static_cast<T*>(nullptr), next_++));
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{topic_name_, std::string(horus::TypeInfo<T>::name)}};
  }

 private:
  std::string topic_name_;
  horus::Topic<T> out_;
  int count_;
  int next_ = 1;
};

/// Takes whatever its topic holds each tick.
template <class T>
class Sink : public horus::Node {
 public:
  explicit Sink(std::string topic) : topic_name_(std::move(topic)), in_(topic_name_) {}
  std::string_view name() const override { return "cpp_sink"; }
  void tick() override {
    while (in_.try_recv()) {
    }
  }
  std::vector<horus::TopicMetadata> subscribers() const override {
    return {{topic_name_, std::string(horus::TypeInfo<T>::name)}};
  }

 private:
  std::string topic_name_;
  horus::Topic<T> in_;
};

template <class T>
int record_session(const std::string& topic, int count) {
  horus::Scheduler sched(horus::SchedulerConfig{}.handle_signals(false).recording(true));
  sched.add(std::make_shared<Driver<T>>(topic, count)).order(0).build();
  sched.add(std::make_shared<Sink<T>>(topic)).order(1).build();
  for (int i = 0; i < count; ++i) {
    sched.tick_once();
    // The recorder reads the topic on its own thread: ticks at a robot's pace, not a busy loop.
    std::this_thread::sleep_for(1ms);
  }
  for (const auto& file : sched.stop_recording()) std::printf("%s\n", file.c_str());
  return 0;
}

template <class T>
class Talker : public horus::Node {
 public:
  explicit Talker(const std::string& topic_name) : topic_(topic_name) {}
  std::string_view name() const override { return "cpp_talker"; }
  void tick() override {
    ++sent_;
    if (!topic_.send(make(static_cast<T*>(nullptr), sent_)))
      HORUS_LOG_WARN("send %d failed", sent_);
    if (sent_ % 10 == 1) HORUS_LOG_INFO("sent %d", sent_);
    if (sent_ == 1) {
      std::printf("ready\n");
      std::fflush(stdout);
    }
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{topic_.name(), std::string(horus::TypeInfo<T>::name)}};
  }

 private:
  horus::Topic<T> topic_;
  int sent_ = 0;
};

template <class T>
int talk(const std::string& topic_name, int hz) {
  const horus::Rate rate = horus::Rate::hz(static_cast<double>(hz));
  horus::Scheduler sched{horus::SchedulerConfig{}.name("cpp_peer").tick_rate(rate)};
  sched.add(std::make_shared<Talker<T>>(topic_name)).rate(rate).build();
  // The test holds stdin open while it looks at the running process; end of input stops it.
  std::thread([&sched] {
    std::string line;
    while (std::getline(std::cin, line)) {
    }
    sched.stop();
  }).detach();
  return sched.run();
}

template <class T>
int run(std::string_view role, const std::string& topic, int count) {
  if (role == "node") return talk<T>(topic, count);
  if (role == "session") return record_session<T>(topic, count);
  return role == "pub" ? publish<T>(topic, count) : subscribe<T>(topic, count);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: %s pub|sub|node|session cmdvel|image|dict TOPIC COUNT|HZ\n",
                 argv[0]);
    return 2;
  }
  const std::string_view role = argv[1];
  const std::string_view kind = argv[2];
  const std::string topic = argv[3];
  const int count = std::atoi(argv[4]);
  if ((role != "pub" && role != "sub" && role != "node" && role != "session") || count <= 0) {
    std::fprintf(stderr, "bad role or count\n");
    return 2;
  }
  if (kind == "cmdvel") return run<CmdVel>(role, topic, count);
  if (kind == "image") return run<CompressedImage>(role, topic, count);
  if (kind == "dict") return run<GenericMessage>(role, topic, count);
  std::fprintf(stderr, "unknown kind %.*s\n", static_cast<int>(kind.size()), kind.data());
  return 2;
}
