// horus::Scheduler and NodeBuilder: the public surface, forwarding to detail::SchedulerImpl.
#include "horus/scheduler.hpp"

#include <cerrno>
#include <string>

#include "horus/error.hpp"
#include "scheduler_impl.hpp"

namespace horus {

std::string detail::program_name() {
  // glibc's basename of argv[0], whole (the kernel's comm is cut at 15 characters).
  const std::string name = program_invocation_short_name;
  return name.empty() ? "horus" : name;
}

std::string_view to_string(ExecutionClass c) noexcept {
  switch (c) {
    case ExecutionClass::BestEffort:
      return "BestEffort";
    case ExecutionClass::Rt:
      return "Rt";
    case ExecutionClass::Compute:
      return "Compute";
    case ExecutionClass::Event:
      return "Event";
    case ExecutionClass::AsyncIo:
      return "AsyncIo";
  }
  return "?";
}

std::string_view to_string(SchedulerStatus s) noexcept {
  switch (s) {
    case SchedulerStatus::Idle:
      return "idle";
    case SchedulerStatus::Running:
      return "running";
    case SchedulerStatus::Stopped:
      return "stopped";
  }
  return "?";
}

Scheduler& NodeBuilder::build() {
  scheduler_->impl_->build(config_);
  return *scheduler_;
}

Scheduler::Scheduler(SchedulerConfig config)
    : impl_(std::make_shared<detail::SchedulerImpl>(std::move(config))) {}

Scheduler::~Scheduler() { impl_->finish(); }

NodeBuilder Scheduler::add(std::shared_ptr<Node> node) {
  return NodeBuilder(*this, impl_->add(std::move(node)));
}

Scheduler& Scheduler::add(const RunNode& node) {
  return add(node.node()).configure(node.config()).build();
}

void Scheduler::add_critical_node(std::string_view name, std::chrono::nanoseconds timeout) {
  impl_->add_critical_node(name, timeout);
}

int Scheduler::run() { return impl_->run(std::nullopt); }
int Scheduler::run_for(std::chrono::nanoseconds duration) { return impl_->run(duration.count()); }
void Scheduler::tick_once() { impl_->tick_once(nullptr); }
void Scheduler::tick_once(const std::vector<std::string>& names) { impl_->tick_once(&names); }
void Scheduler::tick_for(std::chrono::nanoseconds duration, const std::vector<std::string>& names) {
  impl_->tick_for(duration.count(), names.empty() ? nullptr : &names);
}
void Scheduler::stop() noexcept { impl_->request_stop("stop() called", false); }

bool Scheduler::set_node_rate(std::string_view name, Rate rate) {
  return impl_->set_node_rate(name, rate);
}
bool Scheduler::set_tick_budget(std::string_view name, std::chrono::nanoseconds budget) {
  return impl_->set_tick_budget(name, budget);
}
bool Scheduler::remove_node(std::string_view name) { return impl_->remove_node(name); }

SchedulerStatus Scheduler::status() const noexcept { return impl_->status(); }
bool Scheduler::is_running() const noexcept { return impl_->in_loop(); }
std::uint64_t Scheduler::current_tick() const noexcept { return impl_->current_tick(); }
const std::string& Scheduler::name() const noexcept { return impl_->config().name(); }
const SchedulerConfig& Scheduler::config() const noexcept { return impl_->config(); }
std::string Scheduler::stop_reason() const { return impl_->stop_reason(); }

std::size_t Scheduler::node_count() const { return impl_->ordered_slots().size(); }

std::vector<std::string> Scheduler::node_names() const {
  std::vector<std::string> names;
  for (const auto& s : impl_->ordered_slots()) names.push_back(s->name);
  return names;
}

bool Scheduler::has_node(std::string_view name) const { return impl_->find(name) != nullptr; }

std::optional<NodeInfo> Scheduler::node_info(std::string_view name) const {
  const auto slot = impl_->find(name);
  if (!slot) return std::nullopt;
  return impl_->info(*slot);
}

std::vector<NodeInfo> Scheduler::nodes() const {
  std::vector<NodeInfo> out;
  for (const auto& s : impl_->ordered_slots()) out.push_back(impl_->info(*s));
  return out;
}

std::optional<NodeMetrics> Scheduler::node_metrics(std::string_view name) const {
  const auto slot = impl_->find(name);
  if (!slot) return std::nullopt;
  return impl_->metrics(*slot);
}

SafetyStats Scheduler::safety_stats() const { return impl_->safety_stats(); }

std::string Scheduler::timing_report() const { return impl_->timing_report(); }

bool Scheduler::has_full_rt() const {
  return impl_->config().rt() && impl_->degradations().empty();
}
std::vector<std::string> Scheduler::degradations() const { return impl_->degradations(); }
RtCapabilities Scheduler::capabilities() const { return impl_->capabilities(); }
const Blackbox* Scheduler::blackbox() const noexcept { return impl_->blackbox(); }

void Scheduler::dump_blackbox(const std::filesystem::path& path) const {
  const Blackbox* box = impl_->blackbox();
  if (box == nullptr) {
    throw Error("horus::Scheduler '" + name() + "': dump_blackbox needs blackbox_mb > 0");
  }
  box->write_to(path);
}

bool Scheduler::is_recording() const noexcept { return impl_->is_recording(); }
std::vector<std::filesystem::path> Scheduler::stop_recording() { return impl_->stop_recording(); }
std::vector<std::string> Scheduler::list_recordings() const { return horus::list_recordings(); }
bool Scheduler::delete_recording(std::string_view name) { return horus::delete_recording(name); }

}  // namespace horus
