// Logging for node code (seed 000's hlog!, seed 001's node.log_info / log_warning / ...).
//
//   void tick() override {
//     HORUS_LOG_WARN("obstacle at %.2f m", range);     // arguments not evaluated when filtered
//     horus::log::info("lidar connected on %s", port);  // the same, as a function
//   }
//
// Formatting is printf's (GCC 12 has no <format>): the compiler checks the arguments against the
// format. Inside init(), tick(), shutdown(), on_error() and enter_safe_state() the line carries
// the node's name; elsewhere it carries "-". (The seed drops calls made outside callbacks; a C++
// program's main() and helper threads log too, so here they are kept and marked instead. A
// binding that wants the seed's rule checks current_node().)
//
// Every line goes to two places:
//   - stderr, one line each, in the stable format of format_log_line():
//       2026-11-25T06:22:04.123Z WARN motor: obstacle at 0.28 m
//     A background thread writes them, so a node never waits for the terminal: call flush()
//     before reading stderr yourself (run() and tick_once() do before they return).
//   - the namespace's log ring in shared memory (<root>/@logs/<namespace>, the root being
//     $HORUS_SHM_DIR or /dev/shm/horus-<uid>), which read_log() and the `horus log` command read,
//     from any process of the user, while the programs run and after they end.
// Both are bounded lock-free rings: a call never blocks, takes a lock, allocates or makes a system
// call in the common case (the first call of a process opens the ring; a Scheduler opens it at
// construction), so an Rt tick may log. A line that cannot be placed without waiting is dropped
// and counted (stats().dropped); lines are truncated to kMaxLogText bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace horus {

enum class LogLevel : std::uint8_t { Debug, Info, Warn, Error };

/// "DEBUG", "INFO", "WARN", "ERROR".
std::string_view to_string(LogLevel level) noexcept;

/// Longest message kept (bytes); the rest of a longer one is cut.
inline constexpr std::size_t kMaxLogText = 456;
/// Longest source (node name) kept (bytes).
inline constexpr std::size_t kMaxLogSource = 32;

/// One line as the log ring holds it.
struct LogRecord {
  std::uint64_t sequence = 0;     // position in the ring's history (0 for the first line ever)
  std::int64_t wall_time_ns = 0;  // since the Unix epoch
  std::uint32_t pid = 0;
  LogLevel level = LogLevel::Info;
  std::string source;  // the node's name, "-" outside callbacks, "@<scheduler>" for its own lines
  std::string message;
};

/// What read_log() found: the retained lines, oldest first, and the ring's counters.
struct LogSnapshot {
  std::vector<LogRecord> records;
  std::uint64_t written = 0;  // lines ever placed in the ring (older ones are overwritten)
  std::uint64_t dropped = 0;  // lines a writer gave up on because their slot was still busy
};

/// "<UTC time with ms> <LEVEL> <source>: <message>", without a newline. Stable: tools parse it.
std::string format_log_line(const LogRecord& record);

/// The shared-memory log ring of a namespace (empty: the current one). An absent ring gives an
/// empty snapshot; a file that is not a log ring throws horus::Error naming it.
LogSnapshot read_log(std::string_view namespace_name = {});

namespace log {

/// Lines below this level are discarded before formatting. Default: HORUS_LOG_LEVEL
/// (debug/info/warn/error) when set, else Info.
void set_level(LogLevel level) noexcept;
LogLevel level() noexcept;
bool enabled(LogLevel level) noexcept;

void debug(const char* format, ...) noexcept __attribute__((format(printf, 1, 2)));
void info(const char* format, ...) noexcept __attribute__((format(printf, 1, 2)));
void warn(const char* format, ...) noexcept __attribute__((format(printf, 1, 2)));
void error(const char* format, ...) noexcept __attribute__((format(printf, 1, 2)));

/// A finished line with an explicit source: the hook language bindings use to log in a node's
/// name (the level filter applies). An empty source means "-".
void emit(LogLevel level, std::string_view source, std::string_view message) noexcept;

/// The name of the node whose callback runs on this thread, or "" outside callbacks.
std::string_view current_node() noexcept;

/// Returns once every line logged before the call is on stderr.
void flush() noexcept;

/// This process's counters: lines logged (after the level filter), and lines that did not reach
/// stderr because the writer thread fell a whole ring behind or a slot was busy.
struct Stats {
  std::uint64_t logged = 0;
  std::uint64_t dropped = 0;
};
Stats stats() noexcept;

}  // namespace log
}  // namespace horus

#define HORUS_LOG_AT(level, fn, ...)                                 \
  do {                                                               \
    if (::horus::log::enabled(level)) ::horus::log::fn(__VA_ARGS__); \
  } while (0)
#define HORUS_LOG_DEBUG(...) HORUS_LOG_AT(::horus::LogLevel::Debug, debug, __VA_ARGS__)
#define HORUS_LOG_INFO(...) HORUS_LOG_AT(::horus::LogLevel::Info, info, __VA_ARGS__)
#define HORUS_LOG_WARN(...) HORUS_LOG_AT(::horus::LogLevel::Warn, warn, __VA_ARGS__)
#define HORUS_LOG_ERROR(...) HORUS_LOG_AT(::horus::LogLevel::Error, error, __VA_ARGS__)
