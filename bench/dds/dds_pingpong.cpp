// The DDS bridge's ping-pong for bench/dds/run.sh: a CmdVel (16 B) sent on topic `ping` by one
// process and echoed on topic `pong` by another, timed by the pinging one (round trip / 2, as
// ddsperf reports it). Each role runs in the namespace HORUS_NAMESPACE and HORUS_SHM_DIR give it.
//
//   dds_pingpong ping ROUND_TRIPS [DOMAIN]   pings ROUND_TRIPS times after a warm-up, each as soon
//                                            as the last answer came (blocking recv), and prints
//                                            one line of JSON: p50/p99 of round trip / 2 in us;
//                                            with DOMAIN its scheduler's Network exports `ping`
//                                            and imports `pong` on that DDS domain
//   dds_pingpong echo [DOMAIN]               answers each ping on `pong` until stdin ends; with
//                                            DOMAIN its Network imports `ping` and exports `pong`
//   dds_pingpong bridge DOMAIN EXPORT IMPORT a bridge process: horus::dds::DdsBridge exporting
//                                            topic EXPORT and importing IMPORT, until stdin ends
//   dds_pingpong send COUNT [DOMAIN]         for strace: COUNT sends on `ping` 1 ms apart (with
//                                            DOMAIN exported by its Network) between the lines
//                                            "sending" and "sent", on the process's first thread
//
// Every role says `ready` once set up. Each line goes out in one write(2), never through stdio's
// buffer: on a pipe stdio holds a line until the buffer fills or the process ends, and the
// bridge's own lines (written whole from its threads) would pass a `ready` still held there.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <horus/dds_bridge.hpp>
#include <horus/horus.hpp>
#include <horus/msg/cmd_vel.hpp>

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using horus::msg::CmdVel;

// Round trips after the first answer that are not counted: caches, lazy set-up.
constexpr int kWarmUp = 1000;
// How long the pinger waits for an answer before sending its ping again: while the bridges
// match their endpoints a ping can be carried by nobody.
constexpr auto kResendAfter = 50ms;
constexpr auto kFirstAnswerWithin = 60s;

void say(const std::string& text) {
  const std::string line = text + "\n";
  if (::write(STDOUT_FILENO, line.data(), line.size()) != static_cast<ssize_t>(line.size())) {
    throw std::runtime_error("cannot write to stdout");
  }
}

// Set once stdin ends (run.sh closes it to stop a role), so the bridge's DDS entities are deleted
// and the next run's peers do not see writers linger until their lease ends.
std::atomic<bool> stdin_ended{false};

void watch_stdin() {
  std::thread([] {
    std::string ignored;
    while (std::getline(std::cin, ignored)) {
    }
    stdin_ended.store(true);
  }).detach();
}

// With a domain, a scheduler whose Network carries the topics in this process (none without).
std::unique_ptr<horus::Scheduler> scheduler_carrying(const std::vector<std::string>& exported,
                                                     const std::vector<std::string>& imported,
                                                     std::optional<int> domain) {
  if (!domain) return nullptr;
  return std::make_unique<horus::Scheduler>(
      horus::SchedulerConfig{}
          .name("dds_pingpong")
          .network({.export_ = exported, .import_ = imported, .domain = *domain}));
}

std::optional<int> domain_at(const std::vector<std::string>& args, std::size_t index) {
  if (index >= args.size()) return std::nullopt;
  return std::stoi(args[index]);
}

int ping(long round_trips, std::optional<int> domain) {
  horus::Topic<CmdVel> pings{"ping"};
  horus::Topic<CmdVel> pongs{"pong"};
  const auto scheduler = scheduler_carrying({"ping"}, {"pong"}, domain);
  say("ready");
  // One round trip: `seq` goes out and comes back; answers to earlier pings are passed over.
  const auto round_trip = [&](std::uint64_t seq, Clock::duration patience) {
    const auto sent = Clock::now();
    pings.send(CmdVel{.stamp_nanos = seq});
    const auto give_up = sent + patience;
    for (;;) {
      const auto now = Clock::now();
      if (now >= give_up) return std::optional<Clock::duration>{};
      const auto answer = pongs.recv(give_up - now);
      if (answer && answer->stamp_nanos == seq) return std::optional{Clock::now() - sent};
    }
  };
  std::uint64_t seq = 0;
  const auto first_deadline = Clock::now() + kFirstAnswerWithin;
  while (!round_trip(++seq, kResendAfter)) {
    if (Clock::now() > first_deadline) {
      throw std::runtime_error("no answer on 'pong' within " +
                               std::to_string(kFirstAnswerWithin.count()) + " s");
    }
  }
  std::vector<double> halves;
  halves.reserve(static_cast<std::size_t>(round_trips));
  long resent = 0;
  for (long i = 0; i < kWarmUp + round_trips; ++i) {
    std::optional<Clock::duration> took;
    while (!(took = round_trip(++seq, 1s))) ++resent;
    if (i >= kWarmUp) {
      halves.push_back(std::chrono::duration<double, std::micro>(*took).count() / 2);
    }
  }
  std::sort(halves.begin(), halves.end());
  const auto at = [&](double fraction) {
    return halves[std::min(halves.size() - 1, static_cast<std::size_t>(
                                                  fraction * static_cast<double>(halves.size())))];
  };
  char json[160];
  std::snprintf(json, sizeof json, R"({"p50": %.2f, "p99": %.2f, "samples": %zu, "resent": %ld})",
                at(0.50), at(0.99), halves.size(), resent);
  say(json);
  return 0;
}

int echo(std::optional<int> domain) {
  horus::Topic<CmdVel> pings{"ping"};
  horus::Topic<CmdVel> pongs{"pong"};
  const auto scheduler = scheduler_carrying({"pong"}, {"ping"}, domain);
  watch_stdin();
  say("ready");
  while (!stdin_ended.load(std::memory_order_relaxed)) {
    if (const auto message = pings.recv(100ms)) pongs.send(*message);
  }
  return 0;
}

int bridge(int domain, const std::string& exported, const std::string& imported) {
  horus::dds::DdsBridge carrying{{.export_ = {exported}, .import_ = {imported}, .domain = domain},
                                 "",
                                 [](const std::string& failure) {
                                   std::fprintf(stderr, "bridge stopped: %s\n", failure.c_str());
                                 }};
  watch_stdin();
  say("ready");
  while (!stdin_ended.load()) std::this_thread::sleep_for(100ms);
  return 0;
}

int send(long count, std::optional<int> domain) {
  horus::Topic<CmdVel> pings{"ping"};
  const auto scheduler = scheduler_carrying({"ping"}, {}, domain);
  pings.send(CmdVel{});  // the topic's first send: its one-time set-up is not what is counted
  // The bridge looks for topics to export every half second: by now it carries this one.
  std::this_thread::sleep_for(1500ms);
  say("ready");
  say("sending");
  for (long i = 0; i < count; ++i) {
    pings.send(CmdVel{.stamp_nanos = static_cast<std::uint64_t>(i)});
    std::this_thread::sleep_for(1ms);
  }
  say("sent");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  const std::string role = args.empty() ? "" : args[0];
  try {
    if (role == "ping" && (args.size() == 2 || args.size() == 3)) {
      return ping(std::stol(args[1]), domain_at(args, 2));
    }
    if (role == "echo" && args.size() <= 2) return echo(domain_at(args, 1));
    if (role == "bridge" && args.size() == 4) return bridge(std::stoi(args[1]), args[2], args[3]);
    if (role == "send" && (args.size() == 2 || args.size() == 3)) {
      return send(std::stol(args[1]), domain_at(args, 2));
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "dds_pingpong %s: %s\n", role.c_str(), error.what());
    return 1;
  }
  std::fprintf(stderr,
               "usage: %s ping ROUND_TRIPS [DOMAIN] | echo [DOMAIN] | bridge DOMAIN EXPORT IMPORT "
               "| send COUNT [DOMAIN]\n",
               argv[0]);
  return 2;
}
