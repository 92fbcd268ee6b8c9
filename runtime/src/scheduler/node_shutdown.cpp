// Shutting nodes down: each shutdown() on a helper thread bounded by shutdown_timeout, in
// reverse order, and removals requested while running.
#include <condition_variable>
#include <cstdio>
#include <exception>
#include <mutex>
#include <thread>

#include "scheduler_impl.hpp"

namespace horus::detail {

void SchedulerImpl::shutdown_node(const SlotPtr& slot, bool removing) noexcept {
  NodeSlot& s = *slot;
  if (s.initialized && !s.shut_down)
    s.stopped_at_ns.store(monotonic_ns(), std::memory_order_relaxed);
  if (s.initialized && !s.shut_down) {
    if (s.tick_started_ns.load(std::memory_order_acquire) != 0) {
      // Its thread is still inside tick() (detached at teardown): calling shutdown() now would
      // run two methods of one node at once.
      record(BlackboxEventKind::NodeShutdownFailed, s, 0, "still inside tick(); skipped");
      log(LogLevel::Error, "node '%s' never returned from tick(); shutdown() skipped",
          s.name.c_str());
      s.state.store(NodeState::Error);
      s.shut_down = true;
    } else {
      // A crashed node is still shut down (to zero its actuators) but keeps its failure state.
      const NodeState before = s.state.load();
      const bool failed_before = before == NodeState::Crashed || before == NodeState::Error;
      s.state.store(NodeState::Stopping);
      struct Outcome {
        std::mutex mutex;
        std::condition_variable done_cv;
        bool done = false;
        std::exception_ptr error;
      };
      auto outcome = std::make_shared<Outcome>();
      bool finished = false;
      try {
        // A helper thread bounds a hanging shutdown(): it is abandoned (and the node leaked)
        // after shutdown_timeout so the other nodes still shut down.
        std::thread worker([slot, outcome, self = shared_from_this()] {
          std::exception_ptr error;
          {
            TickContextScope scope(&slot->context);
            try {
              slot->node->shutdown();
            } catch (...) {
              error = std::current_exception();
            }
          }
          std::lock_guard lock(outcome->mutex);
          outcome->error = error;
          outcome->done = true;
          outcome->done_cv.notify_all();
        });
        {
          std::unique_lock lock(outcome->mutex);
          finished = outcome->done_cv.wait_for(lock, config_.shutdown_timeout(),
                                               [&] { return outcome->done; });
        }
        if (finished) {
          worker.join();
        } else {
          worker.detach();
        }
      } catch (...) {
        log(LogLevel::Error, "node '%s': could not start its shutdown thread", s.name.c_str());
      }
      s.shut_down = true;
      if (!finished) {
        const long long ms = static_cast<long long>(config_.shutdown_timeout().count() / 1'000'000);
        char why[96];
        std::snprintf(why, sizeof(why), "shutdown() did not return within %lld ms; abandoned", ms);
        handle_failure(s, Phase::Shutdown, why, 0);
        s.state.store(NodeState::Error);
      } else if (outcome->error) {
        handle_failure(s, Phase::Shutdown, exception_text(outcome->error), 0);
        s.state.store(failed_before ? before : NodeState::Stopped);
      } else {
        s.state.store(failed_before ? before : NodeState::Stopped);
        record(BlackboxEventKind::NodeShutdown, s);
      }
    }
  } else if (!s.initialized) {
    s.state.store(s.state.load() == NodeState::Error ? NodeState::Error : NodeState::Stopped);
  }
  // Its store stays (values readable, owner not running); writes are refused from now on.
  s.params.reset();
  if (removing) {
    s.removed.store(true, std::memory_order_release);
    record(BlackboxEventKind::NodeRemoved, s);
  }
}

void SchedulerImpl::shutdown_all() noexcept {
  std::vector<SlotPtr> slots;
  {
    std::lock_guard lock(mutex_);
    slots = slots_;
  }
  for (auto it = slots.rbegin(); it != slots.rend(); ++it) {
    if (!(*it)->removed.load()) shutdown_node(*it, false);
  }
}

void SchedulerImpl::purge_removed() noexcept {
  if (!removals_pending_.exchange(false, std::memory_order_acq_rel)) return;
  std::vector<SlotPtr> pending;
  {
    std::lock_guard lock(mutex_);
    for (const SlotPtr& s : slots_) {
      if (s->remove_requested.load() && !s->removed.load()) pending.push_back(s);
    }
  }
  for (const SlotPtr& s : pending) shutdown_node(s, true);
  std::lock_guard lock(mutex_);
  std::erase_if(slots_, [](const SlotPtr& s) { return s->removed.load(); });
  structure_version_.fetch_add(1, std::memory_order_release);
}

void SchedulerImpl::finish() noexcept {
  request_stop("scheduler destroyed", false);
  if (active_.load()) return;  // a loop on another thread still owns the nodes
  if (prepared_ && !finished_) {
    shutdown_all();
    finished_ = true;
  }
  if (view_) view_->end();
  if (network_) network_->end();
}

}  // namespace horus::detail
