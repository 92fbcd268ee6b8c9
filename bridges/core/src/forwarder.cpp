#include "horus/bridge/forwarder.hpp"

#include <unistd.h>

#include <exception>
#include <utility>

namespace horus::bridge {

Forwarder::Forwarder(std::string label, std::shared_ptr<void> keep_alive)
    : label_(std::move(label)), keep_alive_(std::move(keep_alive)) {}

Forwarder::~Forwarder() { stop(); }

void Forwarder::start(std::function<void()> loop) {
  thread_ = std::thread([this, loop = std::move(loop)] { guarded(loop); });
}

void Forwarder::guarded(const std::function<void()>& work) noexcept {
  try {
    work();
  } catch (const std::exception& error) {
    {
      const std::lock_guard lock(mutex_);
      broken_ = error.what();
      stopping_.store(true, std::memory_order_relaxed);
    }
    woken_.notify_all();
  }
}

void Forwarder::stop() {
  {
    const std::lock_guard lock(mutex_);
    stopping_.store(true, std::memory_order_relaxed);
  }
  woken_.notify_all();
  if (thread_.joinable()) {
    thread_.join();
  }
}

std::string Forwarder::broken() const {
  const std::lock_guard lock(mutex_);
  return broken_;
}

void Forwarder::failed(const std::string& error, const char* then) {
  const std::uint64_t count = count_failure();
  say(error + " (failure " + std::to_string(count) + " of it); " + then);
}

void Forwarder::say(const std::string& text) const {
  if (text.empty()) {
    return;
  }
  const std::string line = label_ + ": " + text + "\n";
  // One write: the line stays whole beside what other threads print.
  [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, line.data(), line.size());
}

void Forwarder::pause(std::chrono::milliseconds how_long) {
  std::unique_lock lock(mutex_);
  woken_.wait_for(lock, how_long, [this] { return stopping(); });
}

}  // namespace horus::bridge
