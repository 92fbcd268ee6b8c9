// Services between real processes: the test binary re-executes itself (topic_test_support.hpp)
// to play servers and callers. Every wait is bounded, so a failure never hangs.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/scheduler.hpp>
#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <service_test/compute.hpp>
#include <service_test/get_robot_pose.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::HandlerResult;
using horus::ServiceErrorKind;
using service_test::Compute;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using service_test::GetRobotPose;
using service_test::GetRobotPoseRequest;
using service_test::GetRobotPoseResponse;
using topic_test::Child;
using topic_test::PrivateNamespace;

constexpr auto kLong = 20s;

/// Behaviours of the test server (ComputeRequest::behaviour).
constexpr std::uint32_t kAnswer = 0;
constexpr std::uint32_t kFail = 1;
constexpr std::uint32_t kThrow = 2;
/// Announces itself on kBusyTopic, then waits for a message on kGateTopic before answering.
constexpr std::uint32_t kGated = 3;

constexpr const char* kBusyTopic = "svc_test.busy";
constexpr const char* kGateTopic = "svc_test.gate";
constexpr const char* kStopTopic = "svc_test.stop";

// ---- Roles -------------------------------------------------------------------------------------

/// serve: serves Compute and GetRobotPose until a message on kStopTopic (or 60 s).
int role_serve(const std::vector<std::string>&) {
  horus::Topic<ComputeRequest> stop(kStopTopic);
  auto compute =
      horus::ServiceServerBuilder<Compute>()
          .on_request([](const ComputeRequest& req) -> HandlerResult<ComputeResponse> {
            std::this_thread::sleep_for(std::chrono::milliseconds(req.delay_ms));
            if (req.behaviour == kFail) {
              return "cannot add " + std::to_string(req.a);
            }
            if (req.behaviour == kThrow) {
              throw std::runtime_error("handler exploded");
            }
            if (req.behaviour == kGated) {
              horus::Topic<ComputeRequest> gate(kGateTopic);
              horus::Topic<ComputeResponse> busy(kBusyTopic);
              busy.send(ComputeResponse{req.a, 0});
              if (!gate.recv(60s)) {
                return std::string("gate never opened");
              }
            }
            return ComputeResponse{req.a + req.b, static_cast<std::uint32_t>(::getpid())};
          })
          .build();
  auto pose =
      horus::ServiceServerBuilder<GetRobotPose>()
          .on_request([](const GetRobotPoseRequest& req) -> HandlerResult<GetRobotPoseResponse> {
            if (req.robot_name.rfind("arm_", 0) != 0) {
              return "Unknown robot: " + req.robot_name;
            }
            return GetRobotPoseResponse{static_cast<double>(req.robot_name.size()), 2.0, 0.5, 1};
          })
          .build();
  return stop.recv(60s) ? 0 : 30;
}

/// call <caller id> <count>: `count` calls with values only this caller uses; 0 if all were right.
int role_call(const std::vector<std::string>& args) {
  const std::int64_t id = std::stoll(args.at(0));
  const std::int64_t count = std::stoll(args.at(1));
  horus::ServiceClient<Compute> compute;
  horus::ServiceClient<GetRobotPose> pose;
  if (!compute.wait_for_server(kLong) || !pose.wait_for_server(kLong)) {
    std::fprintf(stderr, "caller %lld: no server\n", static_cast<long long>(id));
    return 40;
  }
  for (std::int64_t i = 0; i < count; ++i) {
    const auto sum = compute.call({id * 1'000'000, i, 0, kAnswer}, kLong);
    if (!sum || sum->sum != id * 1'000'000 + i) {
      std::fprintf(stderr, "caller %lld: call %lld: %s\n", static_cast<long long>(id),
                   static_cast<long long>(i),
                   sum ? std::to_string(sum->sum).c_str() : sum.error().to_string().c_str());
      return 41;
    }
    const std::string robot = "arm_" + std::string(static_cast<std::size_t>(id + i % 7), 'x');
    const auto where = pose.call(GetRobotPoseRequest{robot}, kLong);
    if (!where || where->x != static_cast<double>(robot.size())) {
      std::fprintf(stderr, "caller %lld: pose %lld wrong\n", static_cast<long long>(id),
                   static_cast<long long>(i));
      return 42;
    }
  }
  return 0;
}

const bool kRolesRegistered = [] {
  topic_test::roles()["serve"] = role_serve;
  topic_test::roles()["call"] = role_call;
  topic_test::dispatch_role();
  return true;
}();

// ---- Helpers -----------------------------------------------------------------------------------

/// Starts a server child and waits until it is registered.
std::unique_ptr<Child> start_server() {
  auto child = std::make_unique<Child>("serve", std::vector<std::string>{});
  horus::ServiceClient<Compute> compute;
  horus::ServiceClient<GetRobotPose> pose;
  EXPECT_TRUE(compute.wait_for_server(kLong) && pose.wait_for_server(kLong))
      << "the server child never registered";
  return child;
}

void stop_server(Child& child) {
  horus::Topic<ComputeRequest> stop(kStopTopic);
  stop.send(ComputeRequest{});
  EXPECT_EQ(child.wait(kLong), 0);
}

// ---- Tests -------------------------------------------------------------------------------------

TEST(ServiceProcess, ConcurrentClientsInSeveralProcessesEachGetTheirOwnAnswers) {
  PrivateNamespace ns;
  auto server = start_server();
  std::vector<std::unique_ptr<Child>> callers;
  for (int id = 1; id <= 4; ++id) {
    callers.push_back(
        std::make_unique<Child>("call", std::vector<std::string>{std::to_string(id), "150"}));
  }
  // This process calls at the same time too.
  horus::ServiceClient<Compute> client;
  for (std::int64_t i = 0; i < 150; ++i) {
    const auto sum = client.call({7, i, 0, kAnswer}, kLong);
    ASSERT_TRUE(sum) << sum.error().to_string();
    ASSERT_EQ(sum->sum, 7 + i);
  }
  for (auto& caller : callers) {
    EXPECT_EQ(caller->wait(60s), 0);
  }
  const auto services = horus::list_services();
  ASSERT_EQ(services.size(), 2U);
  EXPECT_EQ(services[0].name, "Compute");
  EXPECT_EQ(services[0].servers, 1U);
  EXPECT_EQ(services[0].server_pid, static_cast<std::uint32_t>(server->pid()));
  EXPECT_EQ(services[1].name, "GetRobotPose");
  stop_server(*server);
}

TEST(ServiceProcess, NoServerIsReportedAtOnce) {
  PrivateNamespace ns;
  horus::ServiceClient<GetRobotPose> client;
  const auto result = client.call(GetRobotPoseRequest{"arm_1"}, 1h);
  ASSERT_FALSE(result);
  EXPECT_EQ(result.error().kind(), ServiceErrorKind::NoServer);
}

TEST(ServiceProcess, TimeoutThenTheNextCallGetsItsOwnAnswer) {
  PrivateNamespace ns;
  auto server = start_server();
  horus::ServiceClient<Compute> client;
  const auto late = client.call({1, 1, 300, kAnswer}, 30ms);
  ASSERT_FALSE(late);
  EXPECT_EQ(late.error().kind(), ServiceErrorKind::Timeout);
  const auto next = client.call({20, 22, 0, kAnswer}, kLong);
  ASSERT_TRUE(next) << next.error().to_string();
  EXPECT_EQ(next->sum, 42);
  stop_server(*server);
}

TEST(ServiceProcess, FailingAndThrowingHandlersAreServiceFailedAndTheServerKeepsServing) {
  PrivateNamespace ns;
  auto server = start_server();
  horus::ServiceClient<Compute> client;
  const auto failed = client.call({9, 0, 0, kFail}, kLong);
  ASSERT_FALSE(failed);
  EXPECT_EQ(failed.error(), horus::ServiceError::service_failed("cannot add 9"));
  const auto threw = client.call({9, 0, 0, kThrow}, kLong);
  ASSERT_FALSE(threw);
  EXPECT_EQ(threw.error(),
            horus::ServiceError::service_failed("the handler threw: handler exploded"));
  horus::ServiceClient<GetRobotPose> pose;
  const auto unknown = pose.call(GetRobotPoseRequest{"leg_1"}, kLong);
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message(), "Unknown robot: leg_1");
  const auto fine = client.call({9, 1, 0, kAnswer}, kLong);
  ASSERT_TRUE(fine) << fine.error().to_string();
  EXPECT_EQ(fine->sum, 10);
  stop_server(*server);
}

TEST(ServiceProcess, ServerKilledMidCallGivesTransportNotAHang) {
  PrivateNamespace ns;
  auto server = start_server();
  horus::Topic<ComputeResponse> busy(kBusyTopic);
  std::optional<horus::ServiceResult<ComputeResponse>> outcome;
  std::thread caller([&] {
    horus::ServiceClient<Compute> client;
    outcome = client.call({1, 1, 0, kGated}, 1h);
  });
  const bool handling = busy.recv(kLong).has_value();
  // Not reaped until the call has returned: a zombie server counts as dead too.
  ::kill(server->pid(), SIGKILL);
  caller.join();
  server->kill();
  ASSERT_TRUE(handling) << "the server never started handling the request";
  ASSERT_TRUE(outcome.has_value());
  ASSERT_FALSE(*outcome);
  EXPECT_EQ(outcome->error().kind(), ServiceErrorKind::Transport) << outcome->error().to_string();

  // Its registration stays behind: later calls are Transport too, and tools see no server.
  horus::ServiceClient<Compute> client;
  EXPECT_EQ(client.call({1, 1, 0, kAnswer}, 1h).error().kind(), ServiceErrorKind::Transport);
  const auto services = horus::list_services();
  ASSERT_FALSE(services.empty());
  EXPECT_EQ(services[0].servers, 0U);
}

TEST(ServiceProcess, ResilientCallRidesOverAServerThatStartsLate) {
  PrivateNamespace ns;
  auto crashed = start_server();
  crashed->kill();
  horus::ServiceClient<Compute> client;
  const auto once =
      client.call_resilient_with({1, 2, 0, kAnswer}, kLong, horus::RetryConfig{}.max_retries(0));
  ASSERT_FALSE(once);
  EXPECT_EQ(once.error().kind(), ServiceErrorKind::Transport);

  std::unique_ptr<Child> successor;
  std::thread starter([&] {
    std::this_thread::sleep_for(100ms);
    successor = std::make_unique<Child>("serve", std::vector<std::string>{});
  });
  const auto answer = client.call_resilient_with(
      {1, 2, 0, kAnswer}, kLong,
      horus::RetryConfig{}.max_retries(1000).initial_backoff(5ms).max_backoff(20ms));
  starter.join();
  ASSERT_TRUE(answer) << answer.error().to_string();
  EXPECT_EQ(answer->sum, 3);
  EXPECT_EQ(answer->server_pid, static_cast<std::uint32_t>(successor->pid()));
  stop_server(*successor);
}

/// Keeps one call in flight from its tick, never blocking; records what each check() said.
class PoseQuery : public horus::Node {
 public:
  std::string_view name() const override { return "PoseQuery"; }
  void tick() override {
    if (!pending_) {
      pending_.emplace(client_.call_async({next_, 1, 0, gated_ ? kGated : kAnswer}, kLong));
    }
    const auto state = pending_->check();
    if (!state) {
      errors.push_back(state.error().to_string());
      pending_.reset();
    } else if (state->has_value()) {
      answers.push_back((*state)->sum);
      pending_.reset();
      gated_ = false;
      ++next_;
    } else {
      ++pending_ticks;
    }
  }

  std::vector<std::int64_t> answers;
  std::vector<std::string> errors;
  int pending_ticks = 0;

 private:
  horus::AsyncServiceClient<Compute> client_;
  std::optional<horus::PendingServiceCall<Compute>> pending_;
  std::int64_t next_ = 10;
  bool gated_ = true;
};

TEST(ServiceProcess, AsyncClientInATickingNode) {
  PrivateNamespace ns;
  auto server = start_server();
  horus::Topic<ComputeResponse> busy(kBusyTopic);
  horus::Topic<ComputeRequest> gate(kGateTopic);
  auto node = std::make_unique<PoseQuery>();
  PoseQuery& query = *node;
  horus::Scheduler scheduler;
  scheduler.add(std::move(node)).build();

  // The server holds the first call until the gate opens: ticks meanwhile see it pending.
  scheduler.tick_once();
  ASSERT_TRUE(busy.recv(kLong)) << "the server never received the call";
  for (int i = 0; i < 5; ++i) {
    scheduler.tick_once();
  }
  EXPECT_EQ(query.pending_ticks, 6);
  EXPECT_TRUE(query.answers.empty());
  gate.send(ComputeRequest{});

  const auto give_up = std::chrono::steady_clock::now() + kLong;
  while (query.answers.size() < 3 && query.errors.empty() &&
         std::chrono::steady_clock::now() < give_up) {
    scheduler.tick_once();
    std::this_thread::sleep_for(200us);
  }
  EXPECT_TRUE(query.errors.empty()) << query.errors.front();
  EXPECT_EQ(query.answers, (std::vector<std::int64_t>{11, 12, 13}));
  stop_server(*server);
}

TEST(ServiceProcess, StoppedServerWithdrawsSoCallsSayNoServer) {
  PrivateNamespace ns;
  auto server = start_server();
  stop_server(*server);
  horus::ServiceClient<Compute> client;
  EXPECT_EQ(client.call({1, 1, 0, kAnswer}, 1h).error().kind(), ServiceErrorKind::NoServer);
  const auto services = horus::list_services();
  ASSERT_EQ(services.size(), 2U);
  EXPECT_EQ(services[0].servers, 0U);
  EXPECT_EQ(services[0].request_type, "service_test.ComputeRequest");
}

}  // namespace
