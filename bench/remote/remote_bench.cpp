// bench/remote: the processes run.sh starts.
//
//   rpc-serve CERTS             a Cap'n Proto RPC echo on 127.0.0.1 (prints "port N"), TLS as
//                               horus-remote's (the robot's certificate)
//   rpc-ping PORT CERTS COUNT   COUNT echoes of a CmdVel's bytes to it (the laptop's certificate)
//   topic-echo                  sends back each CmdVel of topic ping on topic pong
//   topic-ping COUNT NAME       COUNT CmdVels on ping, each waiting for its pong (the row NAME)
//   topic-relay NEAR FAR [hand-off]
//                               the link's topic hops without the link: ping of namespace NEAR
//                               sent on to ping of FAR, pong of FAR back to pong of NEAR, each
//                               direction a thread waiting on its topic (as a link's forwarder);
//                               with hand-off, that thread hands each message to another one
//                               through a queue and an eventfd the other waits on with epoll (as
//                               a forwarder hands it to the event loop)
//   stream-publish SECONDS      CmdVel on cmd_vel at 1 kHz, a 640x480 RGB image on camera (a
//                               CompressedImage) and on pool_camera (a horus::Image) at 30 Hz
//   topic-wait                  how horus-remote would wait on its topics in this environment
//                               (link.hpp: describe_topic_wait)
//   stream-count SECONDS        the rates cmd_vel, camera and pool_camera arrive at, from the
//                               first message on
//
// The pings print "<name> p50 P99 mean" in microseconds, the counter "<topic> RATE" in hertz.
#include <capnp/rpc-twoparty.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "echo.capnp.h"
#include "horus/image.hpp"
#include "horus/msg/cmd_vel.hpp"
#include "horus/msg/compressed_image.hpp"
#include "horus/topic.hpp"
#include "link.hpp"

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kWarmUp = 500;
constexpr auto kPongWait = std::chrono::seconds(2);
constexpr std::uint32_t kWidth = 640;
constexpr std::uint32_t kHeight = 480;

horus::TopicOptions camera_options() {
  horus::TopicOptions options;
  options.capacity = 8;
  options.max_message_size = std::size_t{1} << 20;
  return options;
}

void report(const char* name, std::vector<double> micros) {
  std::sort(micros.begin(), micros.end());
  const double mean =
      std::accumulate(micros.begin(), micros.end(), 0.0) / static_cast<double>(micros.size());
  std::printf("%s %.1f %.1f %.1f\n", name, micros[micros.size() / 2],
              micros[micros.size() * 99 / 100], mean);
}

double micros_since(Clock::time_point start) {
  return std::chrono::duration<double, std::micro>(Clock::now() - start).count();
}

class EchoImpl final : public Echo::Server {
 protected:
  kj::Promise<void> echo(EchoContext context) override {
    context.getResults().setData(context.getParams().getData());
    return kj::READY_NOW;
  }
};

int rpc_serve(const std::string& certs) {
  auto io = kj::setupAsyncIo();
  const auto credentials = horus::bridge::load_tls_credentials(certs, "robot");
  auto tls = horus::bridge::tls_context(credentials, io.provider->getTimer(),
                                        horus::remote::kHandshakeTimeout);
  auto address = io.provider->getNetwork().parseAddress("127.0.0.1:0").wait(io.waitScope);
  auto port = address->listen();
  std::printf("port %u\n", port->getPort());
  std::fflush(stdout);
  auto secured = tls->wrapPort(kj::mv(port));
  capnp::TwoPartyServer server(kj::heap<EchoImpl>());
  server.listen(*secured).wait(io.waitScope);
  return 0;
}

int rpc_ping(const std::string& port, const std::string& certs, int count) {
  auto io = kj::setupAsyncIo();
  const auto credentials = horus::bridge::load_tls_credentials(certs, "laptop");
  auto tls = horus::bridge::tls_context(credentials, io.provider->getTimer(),
                                        horus::remote::kHandshakeTimeout);
  auto address = io.provider->getNetwork().parseAddress("127.0.0.1:" + port).wait(io.waitScope);
  auto stream = tls->wrapClient(address->connect().wait(io.waitScope), "robot").wait(io.waitScope);
  capnp::TwoPartyClient client(*stream);
  auto echo = client.bootstrap().castAs<Echo>();
  const std::vector<capnp::byte> bytes(sizeof(horus::msg::CmdVel), 7);
  std::vector<double> micros;
  for (int i = 0; i < kWarmUp + count; ++i) {
    const auto start = Clock::now();
    auto request = echo.echoRequest();
    request.setData(kj::arrayPtr(bytes.data(), bytes.size()));
    request.send().wait(io.waitScope);
    if (i >= kWarmUp) micros.push_back(micros_since(start));
  }
  report("rpc_echo", std::move(micros));
  return 0;
}

int topic_echo() {
  horus::Topic<horus::msg::CmdVel> ping("ping");
  horus::Topic<horus::msg::CmdVel> pong("pong");
  for (;;) {
    if (const auto message = ping.recv(std::chrono::seconds(1))) pong.send(*message);
  }
}

horus::TopicOptions in_namespace(const std::string& namespace_name) {
  horus::TopicOptions options;
  options.namespace_name = namespace_name;
  return options;
}

/// Sends on each message of `from` to `to` until the process ends.
void relay(horus::Topic<horus::msg::CmdVel>& from, horus::Topic<horus::msg::CmdVel>& to) {
  for (;;) {
    if (const auto message = from.recv(std::chrono::seconds(1))) to.send(*message);
  }
}

/// As relay(), with the hand-off of a link's Forwarder between the thread that waits on `from`
/// and the one that sends on `to`.
void relay_handing_off(horus::Topic<horus::msg::CmdVel>& from,
                       horus::Topic<horus::msg::CmdVel>& to) {
  const int wake = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  const int events = ::epoll_create1(EPOLL_CLOEXEC);
  epoll_event watched{};
  watched.events = EPOLLIN;
  if (wake < 0 || events < 0 || ::epoll_ctl(events, EPOLL_CTL_ADD, wake, &watched) != 0) {
    throw std::runtime_error(std::string("cannot make an eventfd and its epoll: ") +
                             std::strerror(errno));
  }
  std::mutex mutex;
  std::deque<horus::msg::CmdVel> queue;
  std::thread sender([&] {
    for (;;) {
      epoll_event ready{};
      if (::epoll_wait(events, &ready, 1, -1) != 1) continue;
      std::uint64_t count = 0;
      static_cast<void>(::read(wake, &count, sizeof count));
      std::unique_lock lock(mutex);
      while (!queue.empty()) {
        const horus::msg::CmdVel message = queue.front();
        queue.pop_front();
        lock.unlock();
        to.send(message);
        lock.lock();
      }
    }
  });
  for (;;) {
    if (const auto message = from.recv(std::chrono::seconds(1))) {
      std::lock_guard lock(mutex);
      queue.push_back(*message);
      const std::uint64_t one = 1;
      static_cast<void>(::write(wake, &one, sizeof one));
    }
  }
}

int topic_relay(const std::string& near, const std::string& far, bool hand_off) {
  horus::Topic<horus::msg::CmdVel> near_ping("ping", in_namespace(near));
  horus::Topic<horus::msg::CmdVel> far_ping("ping", in_namespace(far));
  horus::Topic<horus::msg::CmdVel> far_pong("pong", in_namespace(far));
  horus::Topic<horus::msg::CmdVel> near_pong("pong", in_namespace(near));
  const auto direction = hand_off ? relay_handing_off : relay;
  std::thread outward([&] { direction(near_ping, far_ping); });
  direction(far_pong, near_pong);
  outward.join();
  return 0;
}

int topic_ping(int count, const std::string& row) {
  horus::Topic<horus::msg::CmdVel> ping("ping");
  horus::Topic<horus::msg::CmdVel> pong("pong");
  std::vector<double> micros;
  std::uint64_t stamp = 0;
  int lost = 0;
  // Until the link (or the relay) carries both ways, pings go unanswered: they are part of the
  // warm-up.
  for (int answered = 0; answered < kWarmUp + count;) {
    horus::msg::CmdVel message;
    message.stamp_nanos = ++stamp;
    const auto start = Clock::now();
    ping.send(message);
    bool back = false;
    while (!back && Clock::now() - start < kPongWait) {
      const auto answer = pong.recv(kPongWait);
      back = answer && answer->stamp_nanos == stamp;
    }
    if (!back) {
      lost += answered > 0;
      continue;
    }
    if (answered++ >= kWarmUp) micros.push_back(micros_since(start));
  }
  report(row.c_str(), std::move(micros));
  if (lost > 0) std::fprintf(stderr, "topic-ping: %d pings unanswered after the warm-up\n", lost);
  return 0;
}

int stream_publish(double seconds) {
  horus::Topic<horus::msg::CmdVel> cmd_vel("cmd_vel");
  horus::Topic<horus::msg::CompressedImage> camera("camera", camera_options());
  horus::msg::CompressedImage image;
  image.format = "rgb8";
  image.width = kWidth;
  image.height = kHeight;
  image.data.assign(std::size_t{kWidth} * kHeight * 3, 128);
  horus::Topic<horus::Image> pool_camera("pool_camera");
  const auto start = Clock::now();
  auto next = start;
  for (std::uint64_t tick = 0; Clock::now() - start < std::chrono::duration<double>(seconds);
       ++tick) {
    horus::msg::CmdVel message;
    message.stamp_nanos = tick;
    cmd_vel.send(message);
    if (tick % 33 == 0) {
      camera.send(image);
      pool_camera.send(horus::Image::make(kHeight, kWidth, horus::ImageEncoding::Rgb8).fill(128));
    }
    next += std::chrono::milliseconds(1);
    std::this_thread::sleep_until(next);
  }
  return 0;
}

int stream_count(double seconds) {
  horus::Topic<horus::msg::CmdVel> cmd_vel("cmd_vel");
  horus::Topic<horus::msg::CompressedImage> camera("camera", camera_options());
  horus::Topic<horus::Image> pool_camera("pool_camera");
  std::uint64_t commands = 0;
  std::uint64_t images = 0;
  std::uint64_t pool_images = 0;
  Clock::time_point first{};
  while (first == Clock::time_point{} ||
         Clock::now() - first < std::chrono::duration<double>(seconds)) {
    bool idle = true;
    if (cmd_vel.try_recv()) {
      ++commands;
      idle = false;
    }
    if (const auto image = camera.try_recv(); image && image->data.size() == kWidth * kHeight * 3) {
      ++images;
      idle = false;
    }
    if (const auto image = pool_camera.try_recv(); image && image->width() == kWidth) {
      ++pool_images;
      idle = false;
    }
    if (!idle && first == Clock::time_point{}) first = Clock::now();
    if (idle) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  const double elapsed = std::chrono::duration<double>(Clock::now() - first).count();
  std::printf("cmd_vel %.1f\ncamera %.1f\npool_camera %.1f\n",
              static_cast<double>(commands) / elapsed, static_cast<double>(images) / elapsed,
              static_cast<double>(pool_images) / elapsed);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  try {
    if (args.size() == 2 && args[0] == "rpc-serve") return rpc_serve(args[1]);
    if (args.size() == 4 && args[0] == "rpc-ping") {
      return rpc_ping(args[1], args[2], std::atoi(args[3].c_str()));
    }
    if (args.size() == 1 && args[0] == "topic-echo") return topic_echo();
    if (args.size() == 3 && args[0] == "topic-ping") {
      return topic_ping(std::atoi(args[1].c_str()), args[2]);
    }
    if ((args.size() == 3 || (args.size() == 4 && args[3] == "hand-off")) &&
        args[0] == "topic-relay") {
      return topic_relay(args[1], args[2], args.size() == 4);
    }
    if (args.size() == 1 && args[0] == "topic-wait") {
      std::printf("%s\n", horus::remote::describe_topic_wait().c_str());
      return 0;
    }
    if (args.size() == 2 && args[0] == "stream-publish")
      return stream_publish(std::atof(args[1].c_str()));
    if (args.size() == 2 && args[0] == "stream-count")
      return stream_count(std::atof(args[1].c_str()));
  } catch (const kj::Exception& e) {
    std::fprintf(stderr, "horus_remote_bench: %s\n", e.getDescription().cStr());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "horus_remote_bench: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "usage: see the top of bench/remote/remote_bench.cpp\n");
  return 2;
}
