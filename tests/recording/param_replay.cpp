// A node whose output depends on its parameters, run by a deterministic scheduler that records
// the session while another thread changes them through set_param(), or that replays such a
// recording (test_record_params.py compares the two).
//
//   param_replay record TICKS [PARAM_FILE]   the writer changes gain and label during the run
//   param_replay replay TICKS RECORDING      no writer: the recording's changes are replayed
//
// Prints one line per tick ("tick N cycle C gain G label L version V output O"), one per change
// the node was offered ("change NAME VALUE SOURCE"), and at the end "recording PATH" (the
// session this run recorded) after "ticks N" (the ticks it ran).
#include <msgpack.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "horus/node.hpp"
#include "horus/params.hpp"
#include "horus/scheduler.hpp"

namespace {

std::string packed_double(double value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack_double(value);
  return std::string(buffer.data(), buffer.size());
}

std::string packed_string(const std::string& value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack(value);
  return std::string(buffer.data(), buffer.size());
}

class GainNode : public horus::Node {
 public:
  GainNode()
      : gain_(declare_param<double>("gain", 1.0, {.min = 0.0, .max = 100.0, .unit = "1"})),
        label_(declare_param<std::string>("label", "plain")) {}

  std::string_view name() const override { return "gain_node"; }

  void tick() override {
    ++ticks_;
    output_ += gain_.get();
    std::printf("tick %llu gain %.17g label %s version %llu output %.17g\n",
                static_cast<unsigned long long>(ticks_), gain_.get(), label_.get().c_str(),
                static_cast<unsigned long long>(gain_.version() + label_.version()), output_);
  }

  horus::ParamVerdict on_param_change(const horus::ParamChange& change) override {
    const std::string value =
        change.name() == "gain" ? std::to_string(change.as<double>()) : change.as<std::string>();
    std::printf("change %s %s %s\n", change.name().c_str(), value.c_str(), change.source.c_str());
    return horus::ParamVerdict::accept();
  }

  std::uint64_t ticks() const { return ticks_.load(); }

 private:
  horus::Param<double> gain_;
  horus::Param<std::string> label_;
  std::atomic<std::uint64_t> ticks_{0};
  double output_ = 0;
};

/// Writes `value` from this (another) thread once the node has ticked `after` times; the write
/// waits for the scheduler's thread to offer it to the node between two ticks.
void write_after(const GainNode& node, std::uint64_t after, const char* name,
                 const std::string& value) {
  while (node.ticks() < after) std::this_thread::yield();
  horus::ParamSetOptions options;
  options.source = "param_replay writer";
  const horus::ParamSetResult result = horus::set_param("gain_node", name, value, options);
  if (!result.accepted) {
    std::fprintf(stderr, "param_replay: %s refused: %s\n", name, result.reason.c_str());
    std::exit(1);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() < 2 || (args[0] != "record" && args[0] != "replay") ||
      (args[0] == "replay" && args.size() != 3)) {
    std::fprintf(stderr, "usage: param_replay record TICKS [PARAM_FILE] | replay TICKS FILE\n");
    return 2;
  }
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  const bool recording = args[0] == "record";
  const std::uint64_t ticks = std::stoull(args[1]);
  horus::SchedulerConfig config;
  config.deterministic(true).recording(true).tick_rate(horus::Rate::hz(100.0));
  if (recording && args.size() == 3) config.params(args[2]);
  if (!recording) config.replay(args[2]);
  horus::Scheduler scheduler(config);
  auto node = std::make_shared<GainNode>();
  scheduler.add(node).build();
  std::thread writer;
  std::atomic<bool> written{!recording};
  if (recording) {
    writer = std::thread([&] {
      write_after(*node, ticks / 3, "gain", packed_double(2.5));
      write_after(*node, 2 * ticks / 3, "label", packed_string("boosted"));
      written = true;
    });
  }
  // Recording, the loop leaves the writer time to reach the node, and goes on until both writes
  // took effect: the replay is then run for as many ticks as this prints.
  std::uint64_t done = 0;
  for (; done < ticks || !written.load(); ++done) {
    scheduler.tick_once();
    if (recording) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (writer.joinable()) writer.join();
  std::printf("ticks %llu\n", static_cast<unsigned long long>(done));
  for (const std::filesystem::path& path : scheduler.stop_recording()) {
    std::printf("recording %s\n", path.c_str());
  }
  return 0;
}
