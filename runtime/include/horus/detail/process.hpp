// Who this process is, and whether another one still runs: the pid cached for hot paths, the
// identity (pid and start time) that shared tables record, and the liveness checks that let a
// process recover what a dead one left behind (a slot, a lease, a sleeper count, a service).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

namespace horus::detail {

/// Whether a process exists: kill(pid, 0), so a zombie still counts (only on slow paths: it is a
/// syscall). Pid 0 is nobody.
bool process_alive(std::uint32_t pid) noexcept;

/// This process's pid as of the last fork: 0 until first asked, and again in a forked child.
inline std::atomic<std::uint32_t> cached_pid{0};
/// Asks the kernel, caches the answer, and (once) has every forked child forget it.
std::uint32_t refresh_pid() noexcept;
/// This process's pid without a syscall. A forked child gets its own, so a handle it inherited
/// neither claims slots nor holds a publisher lease in its parent's name.
inline std::uint32_t this_pid() noexcept {
  const std::uint32_t pid = cached_pid.load(std::memory_order_relaxed);
  return pid != 0 ? pid : refresh_pid();
}

/// A process as shared tables record it: the pid in the low half and, in the high half, when it
/// started (clock ticks since boot, the low 32 bits; 0 when unknown). With the start time, a dead
/// process whose pid the kernel gave to another is still seen dead; both halves are one word, so
/// whoever takes an entry over replaces them together. A bare pid is an identity of unknown start.
inline std::uint32_t identity_pid(std::uint64_t identity) noexcept {
  return static_cast<std::uint32_t>(identity);
}
/// This process's identity: read once, and again in a forked child.
std::uint64_t this_process_identity() noexcept;
/// Whether the process with this identity runs: its pid exists, it has not exited (a zombie
/// has), and (when known) it started when the identity says. A syscall and a read of /proc:
/// slow paths only.
bool identity_alive(std::uint64_t identity) noexcept;
/// When the process with this identity started, in ns since the Unix epoch (to the kernel's
/// clock tick), as tools show it; 0 when the identity's start time is unknown.
std::int64_t identity_start_wall_ns(std::uint64_t identity) noexcept;

/// The program a process runs, as the kernel names it (/proc/<pid>/comm: at most 15 characters),
/// for messages that point at another process; "" when it cannot be read. A slow path.
std::string process_name(std::uint32_t pid);

}  // namespace horus::detail
