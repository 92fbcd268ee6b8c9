// Action latency between two processes pinned to different cores, against what an action is
// built from, in the same run: a service round trip of the same message sizes and a topic hop of
// the feedback message's size.
//
//   horus_action_bench [samples]      prints a Markdown table (p50, p99, mean, ratio to the base)
//
// Rows: (a) send_goal until the client holds the accepted handle, against a plain service call
// of Navigate.send_goal's request and response; (b) the accepted answer until the first feedback
// callback ran (0 when the feedback came first: the server hands the goal to its executor before
// answering). Goals of (a) and (b) are 200 us apart (untimed), so each finds the server idle as a
// service call does. (c) a feedback's publish until its callback ran, against a topic hop of the
// feedback message (one way, both stamped with CLOCK_MONOTONIC, which processes share).
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <horus/action.hpp>
#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <horus_test/action/navigate.hpp>

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using horus_test::action::Navigate;

constexpr int kClientCore = 0;
constexpr int kServerCore = 1;
constexpr const char* kTriggerTopic = "bench.trigger";
constexpr const char* kHopTopic = "bench.hop";
constexpr const char* kStopTopic = "bench.stop";
/// Row (a)'s pause between goals (not timed).
constexpr auto kSettle = std::chrono::microseconds(200);

bool pin(int core) {
  if (static_cast<int>(::sysconf(_SC_NPROCESSORS_ONLN)) <= core) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(core, &set);
  return ::sched_setaffinity(0, sizeof set, &set) == 0;
}

double now_us() {
  return std::chrono::duration<double, std::micro>(Clock::now().time_since_epoch()).count();
}

struct Stats {
  double p50_us;
  double p99_us;
  double mean_us;
};

Stats summarize(std::vector<double> samples) {
  std::sort(samples.begin(), samples.end());
  double sum = 0;
  for (const double s : samples) sum += s;
  const auto at = [&](double q) {
    return samples[std::min(samples.size() - 1,
                            static_cast<std::size_t>(q * static_cast<double>(samples.size())))];
  };
  return {at(0.50), at(0.99), sum / static_cast<double>(samples.size())};
}

/// A failed measurement, said on stderr.
double failed(const char* what, const std::string& why) {
  std::fprintf(stderr, "%s: %s\n", what, why.c_str());
  return -1.0;
}

/// One measurement: returns its microseconds, or a negative number on a failure.
struct Contender {
  const char* label;
  int base;  // index of the contender it is compared with (itself for a base)
  std::function<double()> sample;
  std::vector<double> samples;
};

/// Times every contender in interleaved blocks, so other work on the machine weighs on all alike.
void measure(std::vector<Contender>& contenders, int samples) {
  constexpr int kBlocks = 20;
  const int per_block = std::max(1, samples / kBlocks);
  for (int block = 0; block < kBlocks; ++block) {
    for (Contender& contender : contenders) {
      for (int i = 0; i < per_block / 10 + 1 + per_block; ++i) {
        const double us = contender.sample();
        if (us < 0) {
          std::fprintf(stderr, "%s: a measurement failed\n", contender.label);
          std::exit(1);
        }
        if (i > per_block / 10) contender.samples.push_back(us);  // the first are warm-up
      }
    }
  }
}

// ---- The server process ---------------------------------------------------------------------

horus::TopicOptions in_namespace(const std::string& name) {
  horus::TopicOptions options;
  options.namespace_name = name;
  return options;
}

/// The three namespaces: the quick goals' action (rows a, b), the streaming goal's action (row c),
/// and the base lines (Navigate.send_goal's types served plainly, a bare topic hop).
struct Namespaces {
  std::string quick;
  std::string stream;
  std::string plain;
};

[[noreturn]] void serve(const Namespaces& ns) {
  pin(kServerCore);
  horus::Topic<Navigate::Goal> stop(kStopTopic, in_namespace(ns.plain));
  auto send_goal = horus::ServiceServerBuilder<Navigate::SendGoal>()
                       .on_request([](const Navigate::SendGoal::Request&) {
                         Navigate::SendGoal::Response answer{};
                         answer.accepted = true;
                         return answer;
                       })
                       .options(in_namespace(ns.plain))
                       .build();
  std::thread hop([&ns] {
    horus::Topic<Navigate::Goal> trigger(kTriggerTopic, in_namespace(ns.plain));
    horus::Topic<Navigate::FeedbackMessage> out(kHopTopic, in_namespace(ns.plain));
    for (;;) {
      const std::optional<Navigate::Goal> wanted = trigger.recv(600s);
      if (!wanted || wanted->x < 0) return;
      Navigate::FeedbackMessage message{};
      message.feedback.remaining_m = now_us();
      out.send(message);
    }
  });
  auto quick = horus::ActionServerBuilder<Navigate>()
                   .on_execute([](horus::ServerGoal<Navigate>& goal) {
                     goal.publish_feedback({1, now_us()});
                     goal.succeed({true, goal.goal().x, goal.goal().y, 1});
                   })
                   .options(in_namespace(ns.quick))
                   .build();
  auto stream = horus::ActionServerBuilder<Navigate>()
                    .on_execute([&ns](horus::ServerGoal<Navigate>& goal) {
                      horus::Topic<Navigate::Goal> trigger(kTriggerTopic, in_namespace(ns.stream));
                      std::uint32_t step = 0;
                      while (!goal.is_cancel_requested()) {
                        if (trigger.recv(10ms)) goal.publish_feedback({++step, now_us()});
                      }
                      goal.cancel();
                    })
                    .options(in_namespace(ns.stream))
                    .build();
  stop.recv(600s);
  quick.stop();
  stream.stop();
  horus::Topic<Navigate::Goal>(kTriggerTopic, in_namespace(ns.plain)).send(Navigate::Goal{-1.0});
  hop.join();
  send_goal.stop();
  ::_exit(0);
}

void print_row(const Contender& contender, const Contender& base) {
  const Stats stats = summarize(contender.samples);
  const Stats floor = summarize(base.samples);
  std::printf("| %s | %.1f | %.1f | %.1f | %.2fx | %.2fx |\n", contender.label, stats.p50_us,
              stats.p99_us, stats.mean_us, stats.p50_us / floor.p50_us,
              stats.p99_us / floor.p99_us);
}

}  // namespace

/// Runs the server process and the measurements; prints the table.
int run(const Namespaces& ns, int samples) {
  // Every handle is opened before the server starts, so nothing sent is missed.
  horus::Topic<Navigate::Goal> stop(kStopTopic, in_namespace(ns.plain));
  horus::Topic<Navigate::Goal> hop_trigger(kTriggerTopic, in_namespace(ns.plain));
  horus::Topic<Navigate::FeedbackMessage> hop(kHopTopic, in_namespace(ns.plain));
  horus::Topic<Navigate::Goal> stream_trigger(kTriggerTopic, in_namespace(ns.stream));
  const pid_t child = ::fork();
  if (child == 0) serve(ns);
  const bool pinned = pin(kClientCore);

  horus::ActionClient<Navigate> quick(in_namespace(ns.quick));
  horus::ActionClient<Navigate> stream(in_namespace(ns.stream));
  horus::ServiceClient<Navigate::SendGoal> send_goal(in_namespace(ns.plain));
  if (!quick.wait_for_server(10s) || !stream.wait_for_server(10s) ||
      !send_goal.wait_for_server(10s)) {
    std::fprintf(stderr, "the server process never registered\n");
    ::kill(child, SIGKILL);
    return 1;
  }
  // What the callbacks saw, set on the client's pump thread; the main thread sleeps until then.
  std::mutex seen_mutex;
  std::condition_variable seen_changed;
  std::uint64_t seen_count = 0;
  double feedback_at = 0.0;
  double feedback_stamp = 0.0;
  horus::GoalCallbacks<Navigate> callbacks;
  callbacks.on_feedback = [&](const Navigate::Feedback& feedback) {
    const double at = now_us();
    std::lock_guard lock(seen_mutex);
    feedback_stamp = feedback.remaining_m;
    feedback_at = at;
    ++seen_count;
    seen_changed.notify_one();
  };
  /// The next callback's (arrival, stamp) after `count` were seen; none after a second.
  const auto callback_after = [&](std::uint64_t count) -> std::optional<std::pair<double, double>> {
    std::unique_lock lock(seen_mutex);
    if (!seen_changed.wait_for(lock, 1s, [&] { return seen_count > count; })) return std::nullopt;
    return std::pair(feedback_at, feedback_stamp);
  };
  const auto callbacks_seen = [&] {
    std::lock_guard lock(seen_mutex);
    return seen_count;
  };
  auto streaming = stream.send_goal(Navigate::Goal{}, 1s, callbacks);
  if (!streaming || streaming->state() == horus::GoalState::Rejected) {
    std::fprintf(stderr, "the streaming goal was not accepted\n");
    ::kill(child, SIGKILL);
    return 1;
  }
  std::vector<double> accepted_to_feedback;
  std::vector<Contender> contenders;
  contenders.push_back(
      {"service round trip (Navigate.send_goal's types, a plain service)",
       0,
       [&] {
         const auto start = Clock::now();
         const auto answer = send_goal.call({}, 1s);
         if (!answer || !answer->accepted) return -1.0;
         return std::chrono::duration<double, std::micro>(Clock::now() - start).count();
       },
       {}});
  contenders.push_back({"topic hop (NavigateFeedbackMessage, one way)",
                        1,
                        [&] {
                          hop_trigger.send(Navigate::Goal{});
                          const auto message = hop.recv(1s);
                          if (!message) return -1.0;
                          return now_us() - message->feedback.remaining_m;
                        },
                        {}});
  contenders.push_back(
      {"(a) send_goal -> accepted handle",
       0,
       [&] {
         const std::uint64_t seen = callbacks_seen();
         const auto start = Clock::now();
         auto handle = quick.send_goal(Navigate::Goal{}, 1s, callbacks);
         const double accepted = now_us();
         const double us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
         if (!handle) return failed("send_goal", handle.error().to_string());
         if (handle->state() == horus::GoalState::Rejected) {
           return failed("send_goal", "rejected: " + handle->reason());
         }
         const auto feedback = callback_after(seen);
         if (!feedback) return failed("the first feedback", "none within 1 s");
         accepted_to_feedback.push_back(std::max(0.0, feedback->first - accepted));
         // The next goal finds the server idle (the reject policy), and after a pause also
         // done with this goal's last status, as a plain service call finds its server idle:
         // back to back, the two ends' trailing wakes (the final status, the executor's loop)
         // share the two cores with it.
         if (!handle->result(1s)) return failed("result", "none within 1 s");
         std::this_thread::sleep_for(kSettle);
         return us;
       },
       {}});
  contenders.push_back({"(c) feedback publish -> on_feedback callback",
                        1,
                        [&] {
                          const std::uint64_t seen = callbacks_seen();
                          stream_trigger.send(Navigate::Goal{});
                          const auto feedback = callback_after(seen);
                          if (!feedback) return -1.0;
                          return feedback->first - feedback->second;
                        },
                        {}});
  measure(contenders, samples);
  static_cast<void>(streaming->cancel(1s));
  static_cast<void>(streaming->result(1s));
  stop.send(Navigate::Goal{});
  ::waitpid(child, nullptr, 0);

  Contender feedback_row{"(b) accepted -> first on_feedback callback", 1, {}, {}};
  feedback_row.samples = accepted_to_feedback;
  std::printf("%d samples each (in %s), client and server %s.\n\n", samples,
              "20 interleaved blocks",
              pinned ? "pinned to cores 0 and 1 (the client's pump threads too)"
                     : "not pinned (fewer than 2 cores)");
  std::printf("| measurement | p50 (us) | p99 (us) | mean (us) | p50 / base | p99 / base |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (const Contender& contender : contenders) {
    if (&contender == &contenders[3]) print_row(feedback_row, contenders[1]);
    print_row(contender, contenders[static_cast<std::size_t>(contender.base)]);
  }
  return 0;
}

int main(int argc, char** argv) {
  const int samples = argc > 1 ? std::atoi(argv[1]) : 5000;
  const std::string base = "bench_action_" + std::to_string(::getpid());
  const Namespaces ns{base + "_quick", base + "_stream", base + "_plain"};
  for (const std::string* name : {&ns.quick, &ns.stream, &ns.plain}) horus::remove_namespace(*name);
  const int status = run(ns, samples);  // every handle closed before the namespaces go
  for (const std::string* name : {&ns.quick, &ns.stream, &ns.plain}) horus::remove_namespace(*name);
  return status;
}
