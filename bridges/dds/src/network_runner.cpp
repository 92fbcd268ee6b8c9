// SchedulerConfig::network() as a DdsBridge: the factory the runtime calls (horus/network.hpp).
#include "horus/dds_bridge.hpp"

#include <unistd.h>

#include <string>
#include <vector>

namespace horus::dds {
namespace {

// Patterns as `horus bridge` prints a list of them (Python's): ['a', 'b'].
std::string listed(const std::vector<std::string>& patterns) {
  if (patterns.empty()) {
    return "nothing";
  }
  std::string out = "[";
  for (const std::string& pattern : patterns) {
    out += (out.size() > 1 ? ", '" : "'") + pattern + "'";
  }
  return out + "]";
}

// `horus bridge`'s first line, before anything the bridge says of a topic.
bool said_start(const Network& network) {
  const std::string line = "bridge on DDS domain " + std::to_string(network.domain) +
                           ": exporting " + listed(network.export_) + ", importing " +
                           listed(network.import_) + "; services: exporting " +
                           listed(network.export_services) + ", importing " +
                           listed(network.import_services) + "\n";
  return ::write(STDOUT_FILENO, line.data(), line.size()) >= 0;
}

class BridgeRunner final : public SchedulerCompanion {
 public:
  BridgeRunner(const Network& network, const std::string& namespace_name,
               std::function<void(const std::string&)> on_failure)
      : said_(said_start(network)), bridge_(network, namespace_name, std::move(on_failure)) {}
  void end() noexcept override { bridge_.stop(); }

 private:
  bool said_;
  DdsBridge bridge_;
};

std::unique_ptr<SchedulerCompanion> start_bridge(
    const Network& network, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure) {
  return std::make_unique<BridgeRunner>(network, namespace_name, std::move(on_failure));
}

}  // namespace

void enable_network_bridge() noexcept {
  scheduler_companion_factory<Network>().store(&start_bridge, std::memory_order_release);
}

}  // namespace horus::dds
