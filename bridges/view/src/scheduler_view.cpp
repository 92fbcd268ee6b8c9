// SchedulerConfig::view() as a LiveView: the factory the runtime calls
// (horus/live_view_options.hpp).
#include <unistd.h>

#include <string>

#include "horus/live_view.hpp"

namespace horus::view {
namespace {

class SchedulerView final : public SchedulerCompanion {
 public:
  SchedulerView(LiveViewOptions options, std::function<void(const std::string&)> on_failure)
      : host_(options.listen_address.find(':') == std::string::npos
                  ? options.listen_address
                  : "[" + options.listen_address + "]"),
        view_(std::move(options), std::move(on_failure)) {
    view_.start();
    // The one line that says where to point a viewer (the port, when any free one was asked for).
    const std::string line =
        "live view: ws://" + host_ + ":" + std::to_string(view_.port()) + "/\n";
    [[maybe_unused]] const ssize_t written = ::write(STDOUT_FILENO, line.data(), line.size());
  }
  void end() noexcept override { view_.stop(); }

 private:
  std::string host_;  // as a URL names it: an IPv6 address in brackets
  LiveView view_;
};

std::unique_ptr<SchedulerCompanion> start_view(const LiveViewOptions& options,
                                               const std::string& namespace_name,
                                               std::function<void(const std::string&)> on_failure) {
  LiveViewOptions served = options;
  served.namespace_name = namespace_name;
  return std::make_unique<SchedulerView>(std::move(served), std::move(on_failure));
}

}  // namespace

void enable_scheduler_view() noexcept {
  scheduler_companion_factory<LiveViewOptions>().store(&start_view, std::memory_order_release);
}

}  // namespace horus::view
