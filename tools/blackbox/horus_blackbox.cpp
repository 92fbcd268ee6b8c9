// horus-blackbox: print the events of a scheduler blackbox file, oldest first, then its last
// ticks (node, start, duration, the messages each touched topic carried).
//
//   horus-blackbox FILE [--node NAME] [--kind KIND] [--last N] [--ticks N]
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <string_view>
#include <vector>

#include "horus/blackbox.hpp"

namespace {

int usage(std::FILE* out, int status) {
  std::fprintf(out,
               "usage: horus-blackbox FILE [--node NAME] [--kind KIND] [--last N] [--ticks N]\n"
               "Prints the events of a horus scheduler blackbox (flight recorder) file, then\n"
               "its last ticks: node, start, tick index, duration and, per topic the tick\n"
               "touched, messages sent/received.\n"
               "  --node NAME   only events and ticks of this node (or the scheduler's name)\n"
               "  --kind KIND   only events of this kind, e.g. DeadlineMiss, NodeError\n"
               "  --last N      only the N most recent matching events\n"
               "  --ticks N     the N most recent matching ticks (default 20)\n");
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  std::string file;
  std::string node;
  std::string kind;
  long last = -1;
  long ticks = 20;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    const auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "horus-blackbox: %s needs a value\n", argv[i]);
        std::exit(usage(stderr, 2));
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") return usage(stdout, 0);
    if (arg == "--node") {
      node = value();
    } else if (arg == "--kind") {
      kind = value();
    } else if (arg == "--last" || arg == "--ticks") {
      const char* option = argv[i];
      char* end = nullptr;
      const char* text = value();
      long& count = arg == "--last" ? last : ticks;
      count = std::strtol(text, &end, 10);
      if (end == text || *end != '\0' || count < 0) {
        std::fprintf(stderr, "horus-blackbox: %s needs a non-negative number, got '%s'\n", option,
                     text);
        return 2;
      }
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "horus-blackbox: unknown option %s\n", argv[i]);
      return usage(stderr, 2);
    } else if (file.empty()) {
      file = arg;
    } else {
      std::fprintf(stderr, "horus-blackbox: one file at a time\n");
      return usage(stderr, 2);
    }
  }
  if (file.empty()) return usage(stderr, 2);

  std::vector<horus::BlackboxEvent> events;
  std::vector<horus::BlackboxTick> tick_records;
  try {
    events = horus::read_blackbox(file);
    tick_records = horus::read_blackbox_ticks(file);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "horus-blackbox: %s\n", e.what());
    return 1;
  }
  std::vector<const horus::BlackboxEvent*> shown;
  for (const auto& e : events) {
    if (!node.empty() && e.node_name() != node) continue;
    if (!kind.empty() && horus::to_string(e.kind) != kind) continue;
    shown.push_back(&e);
  }
  std::size_t first = 0;
  if (last >= 0 && shown.size() > static_cast<std::size_t>(last)) {
    first = shown.size() - static_cast<std::size_t>(last);
  }
  std::printf("%s: %zu events (%zu shown)\n", file.c_str(), events.size(), shown.size() - first);
  std::printf("%-27s  %-13s %-18s %-16s %-12s %s\n", "time (UTC)", "tick", "event", "node", "value",
              "detail");
  for (std::size_t i = first; i < shown.size(); ++i) {
    std::printf("%s\n", horus::format_blackbox_event(*shown[i]).c_str());
  }

  std::vector<const horus::BlackboxTick*> shown_ticks;
  for (const auto& t : tick_records) {
    if (node.empty() || t.node_name() == node) shown_ticks.push_back(&t);
  }
  const std::size_t first_tick = shown_ticks.size() > static_cast<std::size_t>(ticks)
                                     ? shown_ticks.size() - static_cast<std::size_t>(ticks)
                                     : 0;
  std::printf("\n%s: %zu ticks (%zu shown)\n", file.c_str(), tick_records.size(),
              shown_ticks.size() - first_tick);
  std::printf("%-27s  %-16s %-13s %12s  %s\n", "tick start (UTC)", "node", "tick", "duration us",
              "topics: sent/received");
  for (std::size_t i = first_tick; i < shown_ticks.size(); ++i) {
    std::printf("%s\n", horus::format_blackbox_tick(*shown_ticks[i]).c_str());
  }
  return 0;
}
