// Services between threads of one process: every behaviour that needs no second process.
// Each test has its own namespace; every wait is bounded.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/detail/shm_segment.hpp>
#include <horus/log.hpp>
#include <horus/scheduler.hpp>
#include <horus/service.hpp>
#include <horus/topic_registry.hpp>
#include <service_test/compute.hpp>
#include <service_test/echo.hpp>
#include <service_test/get_robot_pose.hpp>

namespace {

using namespace std::chrono_literals;
using horus::HandlerResult;
using horus::ServiceErrorKind;
using service_test::Compute;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using service_test::Echo;
using service_test::EchoRequest;
using service_test::EchoResponse;
using service_test::GetRobotPose;
using service_test::GetRobotPoseRequest;
using service_test::GetRobotPoseResponse;

constexpr auto kLong = 10s;

class ServiceThreadTest : public ::testing::Test {
 protected:
  ServiceThreadTest() {
    name_ = "svc" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("HORUS_NAMESPACE", name_.c_str(), 1);
    horus::remove_namespace(name_);
  }
  ~ServiceThreadTest() override {
    horus::remove_namespace(name_);
    ::unsetenv("HORUS_NAMESPACE");
  }

  std::string name_;
};

/// Adds a and b; behaviour 1 fails, 2 throws; sleeps delay_ms first; counts its invocations.
horus::ServiceServer<Compute> compute_server(std::atomic<int>* calls = nullptr) {
  return horus::ServiceServerBuilder<Compute>()
      .on_request([calls](const ComputeRequest& req) -> HandlerResult<ComputeResponse> {
        if (calls != nullptr) {
          calls->fetch_add(1);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(req.delay_ms));
        if (req.behaviour == 1) {
          return "cannot add " + std::to_string(req.a);
        }
        if (req.behaviour == 2) {
          throw std::runtime_error("handler exploded");
        }
        return ComputeResponse{req.a + req.b, static_cast<std::uint32_t>(::getpid())};
      })
      .build();
}

TEST_F(ServiceThreadTest, CallReturnsTheHandlersResponse) {
  auto server = compute_server();
  horus::ServiceClient<Compute> client;
  const auto sum = client.call({40, 2, 0, 0}, kLong);
  ASSERT_TRUE(sum.has_value()) << sum.error().to_string();
  EXPECT_EQ(sum->sum, 42);
  EXPECT_EQ(server.stats().requests, 1U);
}

/// Answers a + b and logs "adding <a>" from the handler.
horus::ServiceServer<Compute> logging_server() {
  return horus::ServiceServerBuilder<Compute>()
      .on_request([](const ComputeRequest& req) {
        HORUS_LOG_INFO("adding %lld", static_cast<long long>(req.a));
        return ComputeResponse{req.a + req.b, 0};
      })
      .build();
}

/// The source of the log line "adding <a>" ("" when there is none).
std::string source_of_adding(long long a) {
  for (const horus::LogRecord& record : horus::read_log().records) {
    if (record.message == "adding " + std::to_string(a)) return record.source;
  }
  return "";
}

TEST_F(ServiceThreadTest, HandlerLinesCarryTheServingNodesNameElseTheServicesName) {
  horus::ServiceClient<Compute> client;
  {
    auto server = logging_server();
    ASSERT_TRUE(client.call(ComputeRequest{1, 1, 0, 0}, kLong));
  }
  EXPECT_EQ(source_of_adding(1), "Compute") << "a server built outside any node";

  class Serving : public horus::Node {
   public:
    std::string_view name() const override { return "adder"; }
    void init() override { server_.emplace(logging_server()); }
    void tick() override {}

   private:
    std::optional<horus::ServiceServer<Compute>> server_;
  };
  horus::Scheduler sched{horus::SchedulerConfig{}.name("services")};
  sched.add(std::make_shared<Serving>()).build();
  sched.tick_once();  // init() builds the server
  ASSERT_TRUE(client.call(ComputeRequest{2, 1, 0, 0}, kLong));
  EXPECT_EQ(source_of_adding(2), "adder") << "a server built in a node's init()";
}

TEST_F(ServiceThreadTest, SerializedRequestAsInTheSpecification) {
  auto server =
      horus::ServiceServerBuilder<GetRobotPose>()
          .on_request([](const GetRobotPoseRequest& req) -> HandlerResult<GetRobotPoseResponse> {
            if (req.robot_name == "arm_1") {
              return GetRobotPoseResponse{1.5, 2.0, 0.0, 7};
            }
            return "Unknown robot: " + req.robot_name;
          })
          .build();
  horus::ServiceClient<GetRobotPose> client;
  const auto pose = client.call(GetRobotPoseRequest{"arm_1"}, kLong);
  ASSERT_TRUE(pose) << pose.error().to_string();
  EXPECT_EQ(*pose, (GetRobotPoseResponse{1.5, 2.0, 0.0, 7}));
  const auto unknown = client.call(GetRobotPoseRequest{"arm_9"}, kLong);
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error(), horus::ServiceError::service_failed("Unknown robot: arm_9"));
}

TEST_F(ServiceThreadTest, NoServerIsReportedWithoutWaiting) {
  horus::ServiceClient<Compute> client;
  const auto result = client.call({1, 2, 0, 0}, 1h);
  ASSERT_FALSE(result);
  EXPECT_EQ(result.error().kind(), ServiceErrorKind::NoServer);
  EXPECT_FALSE(client.wait_for_server(1ms));
}

TEST_F(ServiceThreadTest, FailingAndThrowingHandlersAreServiceFailedAndServingGoesOn) {
  auto server = compute_server();
  horus::ServiceClient<Compute> client;
  const auto failed = client.call({5, 0, 0, 1}, kLong);
  ASSERT_FALSE(failed);
  EXPECT_EQ(failed.error(), horus::ServiceError::service_failed("cannot add 5"));
  const auto threw = client.call({5, 0, 0, 2}, kLong);
  ASSERT_FALSE(threw);
  EXPECT_EQ(threw.error(),
            horus::ServiceError::service_failed("the handler threw: handler exploded"));
  const auto fine = client.call({5, 1, 0, 0}, kLong);
  ASSERT_TRUE(fine);
  EXPECT_EQ(fine->sum, 6);
  EXPECT_EQ(server.stats().failures, 2U);
}

TEST_F(ServiceThreadTest, PodResponseErrorsAreCutSerializedOnesAreWhole) {
  const std::string text(1000, 'e');
  auto compute =
      horus::ServiceServerBuilder<Compute>()
          .on_request([&](const ComputeRequest&) -> HandlerResult<ComputeResponse> { return text; })
          .build();
  auto echo =
      horus::ServiceServerBuilder<Echo>()
          .on_request([&](const EchoRequest&) -> HandlerResult<EchoResponse> { return text; })
          .build();
  horus::ServiceClient<Compute> compute_client;
  horus::ServiceClient<Echo> echo_client;
  EXPECT_EQ(compute_client.call({}, kLong).error().message(), text.substr(0, 236));
  EXPECT_EQ(echo_client.call({}, kLong).error().message(), text);
}

TEST_F(ServiceThreadTest, TimedOutCallsAnswerIsNotTakenForTheNextCall) {
  auto server = compute_server();
  horus::ServiceClient<Compute> client;
  const auto slow = client.call({1, 1, 300, 0}, 20ms);
  ASSERT_FALSE(slow);
  EXPECT_EQ(slow.error().kind(), ServiceErrorKind::Timeout);
  // The server answers the first request while this one waits behind it: that answer is stale.
  const auto next = client.call({2, 2, 0, 0}, kLong);
  ASSERT_TRUE(next) << next.error().to_string();
  EXPECT_EQ(next->sum, 4);
}

TEST_F(ServiceThreadTest, CallOptionalTurnsOnlyTimeoutIntoNothing) {
  horus::ServiceClient<Compute> client;
  const auto no_server = client.call_optional({1, 1, 0, 0}, kLong);
  ASSERT_FALSE(no_server);
  EXPECT_EQ(no_server.error().kind(), ServiceErrorKind::NoServer);
  auto server = compute_server();
  const auto late = client.call_optional({1, 1, 300, 0}, 20ms);
  ASSERT_TRUE(late);
  EXPECT_FALSE(late->has_value());
  const auto answered = client.call_optional({1, 1, 0, 0}, kLong);
  ASSERT_TRUE(answered && answered->has_value());
  EXPECT_EQ((*answered)->sum, 2);
}

TEST_F(ServiceThreadTest, ResilientCallRetriesTimeoutsButNotPermanentErrors) {
  std::atomic<int> calls{0};
  auto server = compute_server(&calls);
  horus::ServiceClient<Compute> client;
  const auto failed = client.call_resilient({1, 1, 0, 1}, kLong);
  ASSERT_FALSE(failed);
  EXPECT_EQ(failed.error().kind(), ServiceErrorKind::ServiceFailed);
  EXPECT_EQ(calls.load(), 1);

  // Every attempt times out: the first try plus two retries reach the handler.
  calls = 0;
  const auto timed_out = client.call_resilient_with(
      {1, 1, 100, 0}, 1ms, horus::RetryConfig{}.max_retries(2).initial_backoff(1ms));
  ASSERT_FALSE(timed_out);
  EXPECT_EQ(timed_out.error().kind(), ServiceErrorKind::Timeout);
  const auto give_up = std::chrono::steady_clock::now() + kLong;
  while (calls.load() < 3 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(1ms);
  }
  std::this_thread::sleep_for(150ms);  // room for a fourth request, which must not exist
  EXPECT_EQ(calls.load(), 3);
  server.stop();

  const auto no_server = client.call_resilient({1, 1, 0, 0}, kLong);
  ASSERT_FALSE(no_server);
  EXPECT_EQ(no_server.error().kind(), ServiceErrorKind::NoServer);
}

TEST_F(ServiceThreadTest, PendingAsyncCallsEachGetTheirOwnAnswer) {
  auto server = compute_server();
  horus::AsyncServiceClient<Compute> client;
  std::vector<horus::PendingServiceCall<Compute>> calls;
  for (std::int64_t i = 0; i < 10; ++i) {
    calls.push_back(client.call_async({i, 100, 0, 0}, kLong));
  }
  const auto give_up = std::chrono::steady_clock::now() + kLong;
  for (std::int64_t i = 9; i >= 0; --i) {
    for (;;) {
      const auto state = calls[static_cast<std::size_t>(i)].check();
      ASSERT_TRUE(state) << state.error().to_string();
      if (state->has_value()) {
        EXPECT_EQ((*state)->sum, i + 100);
        break;
      }
      ASSERT_LT(std::chrono::steady_clock::now(), give_up) << "call " << i << " never completed";
      std::this_thread::sleep_for(1ms);
    }
  }
  // A completed call keeps its outcome.
  EXPECT_EQ((*calls[3].check())->sum, 103);
}

TEST_F(ServiceThreadTest, AsyncCallExpiresAsTimeoutAndWaitBlocksForTheAnswer) {
  auto server = compute_server();
  horus::AsyncServiceClient<Compute> client;
  auto slow = client.call_async({1, 1, 200, 0}, 1ms);
  while (!slow.is_expired()) {
    std::this_thread::sleep_for(1ms);
  }
  const auto expired = slow.check();
  ASSERT_FALSE(expired);
  EXPECT_EQ(expired.error().kind(), ServiceErrorKind::Timeout);
  const auto answer = client.call_async({3, 4, 0, 0}, kLong).wait();
  ASSERT_TRUE(answer) << answer.error().to_string();
  EXPECT_EQ(answer->sum, 7);
}

TEST_F(ServiceThreadTest, AsyncCallWithoutServerCompletesAtOnce) {
  horus::AsyncServiceClient<Compute> client;
  auto call = client.call_async({1, 1, 0, 0}, kLong);
  const auto state = call.check();
  ASSERT_FALSE(state);
  EXPECT_EQ(state.error().kind(), ServiceErrorKind::NoServer);
}

TEST_F(ServiceThreadTest, OversizedMessagesFailWithAReason) {
  auto server = horus::ServiceServerBuilder<Echo>()
                    .on_request([](const EchoRequest& req) {
                      EchoResponse out;
                      for (std::uint32_t i = 0; i < req.repeat; ++i) {
                        out.text += req.text;
                      }
                      return out;
                    })
                    .build();
  horus::ServiceClient<Echo> client;
  const auto too_big_answer = client.call({std::string(1000, 'a'), 100}, kLong);
  ASSERT_FALSE(too_big_answer);
  EXPECT_EQ(too_big_answer.error().kind(), ServiceErrorKind::ServiceFailed);
  EXPECT_NE(too_big_answer.error().message().find("does not fit"), std::string::npos);
  EXPECT_EQ(server.stats().send_failures, 1U);

  const auto too_big_request = client.call({std::string(100'000, 'a'), 1}, kLong);
  ASSERT_FALSE(too_big_request);
  EXPECT_EQ(too_big_request.error().kind(), ServiceErrorKind::Transport);

  const auto fine = client.call({"ab", 3}, kLong);
  ASSERT_TRUE(fine);
  EXPECT_EQ(fine->text, "ababab");
}

TEST_F(ServiceThreadTest, OneLiveServerPerService) {
  auto server = compute_server();
  EXPECT_THROW(compute_server(), horus::Error);
  server.stop();
  auto successor = compute_server();
  horus::ServiceClient<Compute> client;
  EXPECT_TRUE(client.call({1, 2, 0, 0}, kLong));
}

TEST_F(ServiceThreadTest, BuildWithoutHandlerThrows) {
  EXPECT_THROW(horus::ServiceServerBuilder<Compute>().build(), horus::Error);
}

TEST_F(ServiceThreadTest, StoppedServerIsWithdrawnAndListedWithoutServer) {
  auto server = compute_server();
  horus::ServiceClient<Compute> client;
  ASSERT_TRUE(client.wait_for_server(kLong));
  auto listed = horus::list_services();
  ASSERT_EQ(listed.size(), 1U);
  EXPECT_EQ(listed[0].name, "Compute");
  EXPECT_EQ(listed[0].request_type, "service_test.ComputeRequest");
  EXPECT_EQ(listed[0].response_type, "service_test.ComputeResponse");
  EXPECT_EQ(listed[0].fingerprint, Compute::fingerprint());
  EXPECT_EQ(listed[0].servers, 1U);
  EXPECT_EQ(listed[0].server_pid, static_cast<std::uint32_t>(::getpid()));
  EXPECT_EQ(listed[0].clients, 1U);

  server.stop();
  EXPECT_FALSE(server.is_running());
  EXPECT_EQ(client.call({1, 2, 0, 0}, kLong).error().kind(), ServiceErrorKind::NoServer);
  listed = horus::list_services();
  ASSERT_EQ(listed.size(), 1U);
  EXPECT_EQ(listed[0].servers, 0U);
  EXPECT_EQ(listed[0].request_type, "service_test.ComputeRequest");
}

TEST_F(ServiceThreadTest, ClientsOnManyThreadsEachGetTheirOwnAnswers) {
  auto server = compute_server();
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (std::int64_t t = 0; t < 4; ++t) {
    threads.emplace_back([t, &wrong] {
      horus::ServiceClient<Compute> client;
      for (std::int64_t i = 0; i < 200; ++i) {
        const auto sum = client.call({t * 1000, i, 0, 0}, kLong);
        if (!sum || sum->sum != t * 1000 + i) {
          wrong.fetch_add(1);
        }
      }
    });
  }
  for (auto& thread : threads) {
    thread.join();
  }
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(server.stats().requests, 800U);
}

/// Whether some thread or process waits for a flock on the file at `path`: a "->" line of
/// /proc/locks for the file's device and inode.
bool someone_waits_to_lock(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) {
    return false;
  }
  char file[64];
  std::snprintf(file, sizeof file, " %02x:%02x:%llu ", major(info.st_dev), minor(info.st_dev),
                static_cast<unsigned long long>(info.st_ino));
  std::ifstream locks("/proc/locks");
  for (std::string line; std::getline(locks, line);) {
    if (line.find("->") != std::string::npos && line.find(file) != std::string::npos) {
      return true;
    }
  }
  return false;
}

// Every reply topic a client picks is taken by a second subscriber while the client opens it, so
// after kMaxReplyCollisions clashes it shares one. Each clash is made, in order, by holding a
// shared flock on the candidate segment: the client's set-up lock waits for it, and before it is
// let go, a handle here subscribes. Sharing is safe only because each endpoint keeps the answers
// with its own client id: the other endpoint here asks with the same request id as the client's
// first call, each answer reaches both, and each must take only its own.
TEST_F(ServiceThreadTest, AClientClashingOnEveryReplyTopicSharesOneAndGetsItsOwnAnswers) {
  using RequestFrame = horus::detail::ServiceRequestFrame<ComputeRequest>;
  using ResponseFrame = horus::detail::ServiceResponseFrame<ComputeResponse>;
  constexpr int kCandidates = horus::detail::kMaxReplyCollisions + 1;
  auto server = compute_server();
  const std::string folder = horus::detail::namespace_directory(name_);
  std::deque<horus::Topic<ResponseFrame>> others;
  std::vector<int> locks;
  for (int index = 0; index < kCandidates; ++index) {
    const std::string name = horus::detail::reply_topic(Compute::response_topic(), index);
    others.emplace_back(name);
    locks.push_back(::open((folder + "/" + name).c_str(), O_RDONLY | O_CLOEXEC));
    ASSERT_GE(locks.back(), 0);
    ASSERT_EQ(::flock(locks.back(), LOCK_SH), 0);
  }
  int clashes = 0;
  std::thread clasher([&] {
    const auto deadline = std::chrono::steady_clock::now() + kLong;
    for (int index = 0; index < kCandidates; ++index) {
      const std::string path =
          folder + "/" + horus::detail::reply_topic(Compute::response_topic(), index);
      while (!someone_waits_to_lock(path) && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(100us);
      }
      clashes += someone_waits_to_lock(path) ? 1 : 0;
      static_cast<void>(others[static_cast<std::size_t>(index)].try_recv());  // subscribes
      ::flock(locks[static_cast<std::size_t>(index)], LOCK_UN);
    }
  });
  std::optional<horus::ServiceClient<Compute>> client;
  client.emplace();
  clasher.join();
  for (const int lock : locks) {
    ::close(lock);
  }
  ASSERT_EQ(clashes, kCandidates) << "the client did not try each candidate in turn";
  horus::Topic<ResponseFrame>& shared = others.back();

  horus::Topic<RequestFrame> requests(std::string(Compute::request_topic()));
  constexpr std::uint64_t kOtherClient = 0xC0FFEE;
  ASSERT_TRUE(requests.send(horus::detail::request_frame(
      kOtherClient, kCandidates - 1, horus::ServiceRequest<ComputeRequest>{1, {100, 100, 0, 0}})));
  const auto deadline = std::chrono::steady_clock::now() + kLong;
  while (server.stats().requests < 1 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(1ms);
  }
  ASSERT_EQ(server.stats().requests, 1U);

  // The client's first request has id 1 too; the other endpoint's answer sits on the topic.
  const auto sum = client->call({1, 2, 0, 0}, kLong);
  ASSERT_TRUE(sum.has_value()) << sum.error().to_string();
  EXPECT_EQ(sum->sum, 3);

  std::optional<ResponseFrame> own;
  std::optional<ResponseFrame> foreign;
  while (auto frame = shared.try_recv()) {
    (frame->client_id == kOtherClient ? own : foreign) = *frame;
  }
  ASSERT_TRUE(own.has_value());
  EXPECT_EQ(own->payload.sum, 200);
  ASSERT_TRUE(foreign.has_value()) << "the client did not share the last candidate";
  EXPECT_EQ(foreign->payload.sum, 3);
  for (int index = 0; index + 1 < kCandidates; ++index) {
    EXPECT_FALSE(others[static_cast<std::size_t>(index)].try_recv().has_value())
        << "an answer went to reply topic " << index;
  }
}

}  // namespace
