// This process's pid, cached for the hot path and forgotten in every forked child.
#include <pthread.h>
#include <unistd.h>

#include "horus/detail/ring.hpp"

namespace horus::detail {

std::uint32_t refresh_pid() noexcept {
  [[maybe_unused]] static const int forgotten_on_fork =
      ::pthread_atfork(nullptr, nullptr, [] { cached_pid.store(0, std::memory_order_relaxed); });
  const auto pid = static_cast<std::uint32_t>(::getpid());
  cached_pid.store(pid, std::memory_order_relaxed);
  return pid;
}

}  // namespace horus::detail
