#include "telemetry.hpp"

#include <netdb.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "horus/error.hpp"
#include "horus/json_string.hpp"
#include "scheduler_impl.hpp"

namespace horus::detail {

TelemetrySink::TelemetrySink(const std::string& endpoint) {
  const std::string udp = "udp://";
  const std::string file = "file://";
  if (endpoint.rfind(file, 0) == 0 && endpoint.size() > file.size()) {
    file_ = endpoint.substr(file.size());
    if (file_.front() != '/')
      throw Error("telemetry endpoint '" + endpoint + "': the path must be absolute (file:///...)");
    return;
  }
  const std::size_t colon = endpoint.rfind(':');
  if (endpoint.rfind(udp, 0) != 0 || colon == std::string::npos || colon < udp.size() + 1 ||
      colon + 1 == endpoint.size()) {
    throw Error("telemetry endpoint '" + endpoint + "': expected udp://HOST:PORT or file:///PATH");
  }
  std::string host = endpoint.substr(udp.size(), colon - udp.size());
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  const std::string port = endpoint.substr(colon + 1);
  addrinfo hints{};
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  if (const int rc = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    throw Error("telemetry endpoint '" + endpoint + "': " + ::gai_strerror(rc));
  }
  socket_ = ::socket(found->ai_family, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  std::memcpy(&address_, found->ai_addr, found->ai_addrlen);
  address_size_ = found->ai_addrlen;
  ::freeaddrinfo(found);
  if (socket_ < 0) throw Error("telemetry endpoint '" + endpoint + "': cannot open a UDP socket");
}

TelemetrySink::~TelemetrySink() {
  if (socket_ >= 0) ::close(socket_);
}

bool TelemetrySink::publish(const std::string& json) noexcept {
  if (socket_ >= 0) {
    return ::sendto(socket_, json.data(), json.size(), 0,
                    reinterpret_cast<const sockaddr*>(&address_),
                    address_size_) == static_cast<ssize_t>(json.size());
  }
  try {
    // Written beside the target and renamed over it, so a reader never sees half a snapshot.
    const std::string partial = file_ + ".partial";
    {
      std::ofstream out(partial, std::ios::trunc);
      out << json << '\n';
      if (!out.flush()) return false;
    }
    return std::rename(partial.c_str(), file_.c_str()) == 0;
  } catch (...) {
    return false;
  }
}

std::string SchedulerImpl::telemetry_snapshot() const {
  const auto limit = config_.max_deadline_misses();
  std::string json =
      "{\"scheduler\":" + json_string(config_.name()) +
      ",\"time_ns\":" + std::to_string(monotonic_ns() - start_mono_ns_) +
      ",\"cycle\":" + std::to_string(cycle_.load(std::memory_order_relaxed)) +
      ",\"deadline_misses\":" + std::to_string(total_misses_.load(std::memory_order_relaxed)) +
      ",\"max_deadline_misses\":" + (limit ? std::to_string(*limit) : "null") + ",\"nodes\":[";
  bool first = true;
  for (const SlotPtr& slot : ordered_slots()) {
    const NodeMetrics m = metrics(*slot);
    const NodeInfo node = info(*slot);
    json += first ? "{" : ",{";
    first = false;
    json += "\"name\":" + json_string(m.name);
    json += ",\"order\":" + std::to_string(node.order);
    json += ",\"class\":" + json_string(std::string(to_string(node.execution_class)));
    if (node.rate) {
      char rate_hz[32];
      std::snprintf(rate_hz, sizeof(rate_hz), "%.3f", node.rate->hz());
      json += ",\"rate_hz\":" + std::string(rate_hz);
    } else {
      json += ",\"rate_hz\":null";
    }
    json += ",\"state\":" + json_string(std::string(to_string(node.state)));
    json += ",\"health\":" + json_string(std::string(to_string(node.health)));
    json += ",\"total_ticks\":" + std::to_string(m.total_ticks);
    json += ",\"failed_ticks\":" + std::to_string(m.failed_ticks);
    json += ",\"avg_tick_ns\":" + std::to_string(m.avg_tick_duration.count());
    json += ",\"max_tick_ns\":" + std::to_string(m.max_tick_duration.count());
    json += ",\"last_tick_ns\":" + std::to_string(m.last_tick_duration.count());
    for (const auto& [key, topics] :
         {std::pair{"publishers", &node.publishers}, std::pair{"subscribers", &node.subscribers}}) {
      json += std::string(",\"") + key + "\":[";
      for (const TopicMetadata& topic : *topics) {
        json += &topic == topics->data() ? "{" : ",{";
        json += "\"topic\":" + json_string(topic.topic_name) +
                ",\"type\":" + json_string(topic.type_name) + "}";
      }
      json += "]";
    }
    json += ",\"deadline_ns\":" +
            (node.deadline ? std::to_string(node.deadline->count()) : std::string("null"));
    json += ",\"deadline_misses\":" + std::to_string(m.deadline_misses);
    json += ",\"budget_overruns\":" + std::to_string(m.budget_overruns);
    json += ",\"messages_sent\":" + std::to_string(m.messages_sent);
    json += ",\"messages_received\":" + std::to_string(m.messages_received);
    char rate[32];
    std::snprintf(rate, sizeof(rate), "%.3f", m.achieved_rate_hz);
    json += ",\"achieved_rate_hz\":" + std::string(rate) + "}";
  }
  return json + "]}";
}

void SchedulerImpl::export_telemetry() noexcept {
  if (!telemetry_) return;
  bool sent = false;
  try {
    sent = telemetry_->publish(telemetry_snapshot());
  } catch (...) {
    sent = false;
  }
  if (!sent && !telemetry_failure_logged_.exchange(true)) {
    log(LogLevel::Warn, "telemetry to %s failed; further failures are not logged",
        config_.telemetry().c_str());
  }
}

void SchedulerImpl::announce_presence() noexcept {
  if (!presence_) return;
  std::string error;
  bool announced = false;
  try {
    announced = presence_->announce(telemetry_snapshot(), error);
  } catch (...) {
    error = "out of memory";
  }
  if (!announced && !presence_failure_logged_.exchange(true)) {
    log(LogLevel::Warn, "presence announcement failed (%s); further failures are not logged",
        error.c_str());
  }
}

void SchedulerImpl::run_every(std::int64_t interval, std::int64_t end,
                              void (SchedulerImpl::*action)() noexcept) noexcept {
  std::int64_t next = monotonic_ns() + interval;
  while (sleep_until(std::min(next, end))) {
    const std::int64_t now = monotonic_ns();
    if (now >= end) break;
    (this->*action)();
    next = next_on_grid(next, interval, now);
  }
}

void SchedulerImpl::run_presence(std::int64_t end) noexcept {
  announce_presence();
  run_every(kPresenceIntervalNs, end, &SchedulerImpl::announce_presence);
}

void SchedulerImpl::run_telemetry(std::int64_t end) noexcept {
  run_every(config_.telemetry_interval().count(), end, &SchedulerImpl::export_telemetry);
}

}  // namespace horus::detail
