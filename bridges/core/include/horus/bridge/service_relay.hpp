// Calling a local service for the other side of a bridge: the DDS bridge's exported services,
// the remote link's relay on the robot, a live view's calls. LocalServiceCaller owns one worker
// thread per service that makes each call and waits for its answer, so the bridge's own thread
// or event loop never blocks on a local server: a call's outcome comes back through a completion
// callback on the worker, which each bridge turns into its own wake-up (the remote link's
// cross-thread fulfiller, a DDS write).
//
// It calls in one of two ways. With the service's types known (RawServiceType) it moves
// payloads through horus::RawServiceClient, with its failures and texts. Without them (a relay
// that passes a far client's frames through, knowing the response frames' type only once a
// server answered) it moves whole frames: each request goes out under the caller's own client id
// and reply topic, and the answer comes back as the server's response frame; NoServer, Timeout
// and Transport name the host the server runs on (`where`: " on the robot").
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "horus/raw_service.hpp"
#include "horus/raw_topic.hpp"
#include "horus/service_result.hpp"
#include "horus/topic_registry.hpp"

namespace horus::bridge {

/// Opens (or creates) a topic with the name, type and sizes of a TopicInfo, as the bridge opens
/// the topics it learns of (the remote link's `open_topic`).
using TopicOpener = std::function<std::unique_ptr<RawTopic>(const TopicInfo&)>;

/// A reply topic of `service` in the namespace that has its type (`index`: that one, else any):
/// what the service's response frames are. None before a server answered there, or a typed
/// client opened one (a server makes a client's reply topic as it answers it).
std::optional<TopicInfo> reply_topic_type(const std::string& service,
                                          const std::string& namespace_name,
                                          std::optional<std::uint64_t> index = std::nullopt);

/// Reply topic `index` of `service`, with the type of its response frames (`frames`): the topic
/// a server makes as it first answers there.
TopicInfo reply_topic_info(const std::string& service, TopicInfo frames, std::uint64_t index);

class LocalServiceCaller {
 public:
  /// The answer to one call (a response payload, or a response frame, which may itself say the
  /// server failed), or why there is none; with frames, the type of the response frames once
  /// known (always with an answer).
  struct Outcome {
    ServiceResult<std::vector<std::byte>> answer;
    std::optional<TopicInfo> response_type;
  };
  /// Runs on the worker thread, once per call; a call still queued when the caller is destroyed
  /// is dropped with its `done`, uncalled.
  using Done = std::function<void(Outcome)>;

  /// Payloads in and out, through RawServiceClient (horus::Error when the service's topics
  /// carry other types).
  LocalServiceCaller(RawServiceType type, const std::string& namespace_name);
  /// Frames in and out. `request`: the type of the request frames; `response`: the response
  /// frames', when known (else learned from a typed reply topic, or the one the server makes as
  /// it answers); `open` opens the request and reply topics.
  LocalServiceCaller(const std::string& service, const TopicInfo& request,
                     std::optional<TopicInfo> response, const std::string& namespace_name,
                     std::string where, TopicOpener open);
  LocalServiceCaller(const LocalServiceCaller&) = delete;
  LocalServiceCaller& operator=(const LocalServiceCaller&) = delete;
  /// Joins the worker: a frames call in progress ends at once as a Timeout (its `done` runs), a
  /// payload call at its own timeout.
  ~LocalServiceCaller();

  /// Queues a call of `request` (a payload, or a request frame) that waits up to `timeout`.
  void call(std::vector<std::byte> request, std::chrono::milliseconds timeout, Done done);

 private:
  /// How the worker makes one call: RawServiceClient's, or the frames'.
  class Calls;
  class PayloadCalls;
  class FrameCalls;
  struct Job {
    std::vector<std::byte> request;
    std::chrono::milliseconds timeout{};
    Done done;
  };
  void work();

  std::unique_ptr<Calls> calls_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> jobs_;
  std::atomic<bool> stopping_{false};
  /// Last: started once everything it uses is there.
  std::thread worker_;
};

}  // namespace horus::bridge
