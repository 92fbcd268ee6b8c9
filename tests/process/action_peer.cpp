// action_peer: the test action Navigate (tests/schemas/test_actions) served or sent from a
// process of its own, for the process tests here and the Python cross-language tests. Lines on
// stdout, flushed as they happen:
//
//   action_peer serve [--policy reject|preempt|queue] [--capacity N]
//       prints `ready` once serving; serves until SIGTERM or SIGINT. The server of the contract:
//       `feedback_count` feedbacks every `period_us` (`remaining_m` = distance * (N - step) / N),
//       then Succeeded; Aborted with `abort_with` when set; Canceled when asked to cancel.
//   action_peer send X Y [--count N] [--period-us P] [--abort-with TEXT] [--cancel-after K]
//                        [--timeout S]
//       prints `accepted <goal id>`, `feedback <step>` for each feedback, then `<state> <reason>`
//       (`succeeded `, `canceled canceled by a client`, `rejected busy: goal ... is executing`);
//       `error <Kind> <message>` when the goal could not be sent. Exit 0 when it succeeded, 1
//       otherwise, 2 for a bad command line.
// The namespace is HORUS_NAMESPACE's.
#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <horus/action.hpp>
#include <horus_test/action/navigate.hpp>

#include "navigate_server.hpp"

namespace {

using action_test::drive;
using horus_test::action::Navigate;

constexpr std::string_view kUsage =
    "usage: action_peer serve [--policy reject|preempt|queue] [--capacity N]\n"
    "       action_peer send X Y [--count N] [--period-us P] [--abort-with TEXT]\n"
    "                            [--cancel-after K] [--timeout S]\n";

int usage(std::string_view problem) {
  std::fprintf(stderr, "action_peer: %.*s\n%.*s", static_cast<int>(problem.size()), problem.data(),
               static_cast<int>(kUsage.size()), kUsage.data());
  return 2;
}

void say(const std::string& line) {
  std::fputs((line + "\n").c_str(), stdout);
  std::fflush(stdout);
}

int serve(const std::vector<std::string>& args) {
  horus::ActionPolicy policy = horus::ActionPolicy::Reject;
  std::size_t capacity = 8;
  for (std::size_t i = 0; i < args.size(); ++i) {
    if (i + 1 >= args.size()) return usage("option " + args[i] + " needs a value");
    const std::string& value = args[++i];
    if (args[i - 1] == "--policy") {
      if (value == "reject") {
        policy = horus::ActionPolicy::Reject;
      } else if (value == "preempt") {
        policy = horus::ActionPolicy::Preempt;
      } else if (value == "queue") {
        policy = horus::ActionPolicy::Queue;
      } else {
        return usage("unknown policy '" + value + "' (reject, preempt or queue)");
      }
    } else if (args[i - 1] == "--capacity") {
      capacity = std::stoul(value);
    } else {
      return usage("unknown option " + args[i - 1]);
    }
  }
  // Blocked before any thread starts, so only sigwait() below receives them.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute(drive)
                    .policy(policy)
                    .queue_capacity(capacity)
                    .build();
  say("ready");
  int received = 0;
  sigwait(&stop_signals, &received);
  server.stop();
  return 0;
}

int send(const std::vector<std::string>& args) {
  if (args.size() < 2) return usage("send needs X and Y");
  Navigate::Goal goal{};
  goal.x = std::stod(args[0]);
  goal.y = std::stod(args[1]);
  std::optional<std::uint32_t> cancel_after;
  double timeout_s = 2.0;
  for (std::size_t i = 2; i < args.size(); ++i) {
    if (i + 1 >= args.size()) return usage("option " + args[i] + " needs a value");
    const std::string& option = args[i];
    const std::string& value = args[++i];
    if (option == "--count") {
      goal.feedback_count = static_cast<std::uint32_t>(std::stoul(value));
    } else if (option == "--period-us") {
      goal.period_us = static_cast<std::uint32_t>(std::stoul(value));
    } else if (option == "--abort-with") {
      goal.abort_with = value;
    } else if (option == "--cancel-after") {
      cancel_after = static_cast<std::uint32_t>(std::stoul(value));
    } else if (option == "--timeout") {
      timeout_s = std::stod(value);
    } else {
      return usage("unknown option " + option);
    }
  }
  horus::ActionClient<Navigate> client;
  auto handle = client.send_goal(goal, std::chrono::duration_cast<std::chrono::nanoseconds>(
                                           std::chrono::duration<double>(timeout_s)));
  if (!handle) {
    say("error " + std::string(horus::to_string(handle.error().kind())) + " " +
        handle.error().message());
    return 1;
  }
  if (handle->state() != horus::GoalState::Rejected) {
    say("accepted " + handle->id().to_string());
  }
  std::uint32_t received = 0;
  for (;;) {
    std::optional<Navigate::Feedback> feedback = handle->next_feedback(std::chrono::seconds(60));
    if (!feedback) break;  // ended (or a minute without feedback)
    say("feedback " + std::to_string(feedback->step));
    if (cancel_after && ++received == *cancel_after) {
      static_cast<void>(handle->cancel());
    }
  }
  const auto outcome = handle->result(std::chrono::seconds(60));
  if (!outcome) {
    say("error Timeout the goal did not end within a minute");
    return 1;
  }
  say(std::string(horus::to_string(outcome->state)) + " " + outcome->reason);
  return outcome->state == horus::GoalState::Succeeded ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage("no command");
  const std::string command = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  try {
    if (command == "serve") return serve(args);
    if (command == "send") return send(args);
    return usage("unknown command " + command);
  } catch (const std::invalid_argument&) {
    return usage("a number was expected");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "action_peer: %s\n", e.what());
    return 1;
  }
}
