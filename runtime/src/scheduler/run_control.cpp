// The entry points of a run (run, run_for, tick_once, tick_for) and stop requests.
#include <cstdio>
#include <string>
#include <string_view>

#include "horus/error.hpp"
#include "logger.hpp"
#include "scheduler_impl.hpp"
#include "signals.hpp"

namespace horus::detail {

// Marks the scheduler busy for the duration of a run/tick call; a second concurrent call is a
// usage error.
class SchedulerImpl::Activity {
 public:
  Activity(SchedulerImpl& s, bool loop) : s_(s), loop_(loop) {
    bool expected = false;
    if (!s.active_.compare_exchange_strong(expected, true)) {
      throw Error("horus::Scheduler '" + s.config_.name() +
                  "': already running (run/tick_once/tick_for called concurrently or from a tick)");
    }
    if (s.finished_) {
      s.active_.store(false);
      throw Error("horus::Scheduler '" + s.config_.name() +
                  "': its nodes have already been shut down; build a new scheduler");
    }
    if (loop_) s.in_loop_.store(true, std::memory_order_release);
  }
  ~Activity() {
    if (loop_) s_.in_loop_.store(false, std::memory_order_release);
    s_.active_.store(false);
  }
  Activity(const Activity&) = delete;
  Activity& operator=(const Activity&) = delete;

 private:
  SchedulerImpl& s_;
  bool loop_;
};

void SchedulerImpl::tick_once(const std::vector<std::string>* names) {
  Activity activity(*this, false);
  prepare();
  if (!stop_requested_.load()) {
    pass_once(names);
    purge_removed();
  }
  // tick_once() is the testing entry point: what the pass logged is on stderr when it returns.
  log::flush();
}

void SchedulerImpl::tick_for(std::int64_t duration_ns, const std::vector<std::string>* names) {
  if (duration_ns < 0) throw Error("tick_for: duration must not be negative");
  Activity activity(*this, true);
  prepare();
  real_loop(duration_ns, names);
  purge_removed();
}

int SchedulerImpl::run(std::optional<std::int64_t> duration_ns) {
  if (duration_ns && *duration_ns < 0) throw Error("run_for: duration must not be negative");
  {
    Activity activity(*this, true);
    prepare();
    // A node whose init() failed is out of the loop (FailurePolicy::Skip, Ignore, or Fatal without
    // stop_on_failed_init, seed 001's default for Python nodes); with none left, the loop would
    // idle until a signal and then report success.
    const std::string failed_inits = [this] {
      std::lock_guard lock(mutex_);
      std::string text;
      for (const SlotPtr& s : slots_) {
        if (s->state.load() != NodeState::Error || s->restart_pending) return std::string();
        const std::string_view error = s->last_error;  // "init(): <what>", maybe a traceback
        text += (text.empty() ? "node '" : "; node '") + s->name + "' failed in " +
                std::string(error.substr(0, error.find('\n')));
      }
      return text;
    }();
    if (!failed_inits.empty()) request_stop("no node left to run: " + failed_inits, true);
    real_loop(duration_ns, nullptr);
    purge_removed();
    check_signal();
    shutdown_all();
    if (view_) view_->end();
    if (network_) network_->end();
    {
      std::lock_guard lock(mutex_);
      finished_ = true;
    }
    record_scheduler(BlackboxEventKind::SchedulerStop, stop_reason());
    export_telemetry();  // the final figures, also for runs shorter than one interval
    announce_presence();
  }
  if (failed_.load() && blackbox_) {
    try {
      blackbox_->write_to(blackbox_path_);
      log(LogLevel::Error, "blackbox written to %s", blackbox_path_.c_str());
    } catch (const Error& e) {
      log(LogLevel::Error, "%s", e.what());
    }
  }
  log::flush();  // the run's lines precede whatever the caller prints next
  if (config_.verbose()) std::fprintf(stderr, "%s", timing_report().c_str());
  return failed_.load() ? 1 : 0;
}

void SchedulerImpl::request_stop(std::string_view reason, bool failure) noexcept {
  if (failure) failed_.store(true);
  bool expected = false;
  if (stop_requested_.compare_exchange_strong(expected, true)) {
    std::snprintf(stop_reason_, sizeof(stop_reason_), "%.*s", static_cast<int>(reason.size()),
                  reason.data());
    stop_reason_set_.store(true, std::memory_order_release);
    record_scheduler(BlackboxEventKind::StopRequested, reason);
    if (failure || config_.verbose()) {
      log(failure ? LogLevel::Error : LogLevel::Info, "stopping: %s", stop_reason_);
    }
  }
  wake(wake_word_);
}

}  // namespace horus::detail
