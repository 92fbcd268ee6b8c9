// Telemetry export (seed 001's `telemetry`): a JSON snapshot of every node's metrics and health,
// pushed at a fixed rate to a UDP endpoint or written to a file.
#pragma once

#include <netinet/in.h>
#include <sys/socket.h>

#include <string>

namespace horus::detail {

class TelemetrySink {
 public:
  /// "udp://HOST:PORT" (one datagram per snapshot) or "file:///PATH" (replaced atomically each
  /// time). Throws horus::Error saying what is wrong with any other endpoint.
  explicit TelemetrySink(const std::string& endpoint);
  ~TelemetrySink();
  TelemetrySink(const TelemetrySink&) = delete;
  TelemetrySink& operator=(const TelemetrySink&) = delete;

  /// Sends or writes one snapshot; false when it could not (the caller logs it once).
  bool publish(const std::string& json) noexcept;

 private:
  std::string file_;
  int socket_ = -1;
  sockaddr_storage address_{};
  socklen_t address_size_ = 0;
};

}  // namespace horus::detail
