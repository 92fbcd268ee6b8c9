// The logger: level filter, the lines' sources, the stderr writer thread and the rings it feeds.
#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <mutex>
#include <new>
#include <thread>
#include <utility>

#include "horus/detail/log_source.hpp"
#include "horus/detail/ring.hpp"
#include "log_ring.hpp"
#include "logger.hpp"
#include "tick_context.hpp"

namespace horus {
namespace detail {
namespace {

constexpr std::size_t kLocalCapacity = 1024;
constexpr auto kWriterPeriod = std::chrono::milliseconds(10);
/// Writer passes a line may stay unwritten before it counts as abandoned by its writer.
constexpr int kStallPasses = 3;
constexpr int kFlushAttempts = 200;

LogLevel level_from_environment() noexcept {
  const char* value = std::getenv("HORUS_LOG_LEVEL");  // NOLINT(concurrency-mt-unsafe): once
  if (value == nullptr) return LogLevel::Info;
  const std::string_view text = value;
  if (text == "debug") return LogLevel::Debug;
  if (text == "warn") return LogLevel::Warn;
  if (text == "error") return LogLevel::Error;
  return LogLevel::Info;
}

void write_all(const char* data, std::size_t size) noexcept {
  while (size > 0) {
    const ssize_t n = ::write(STDERR_FILENO, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return;
    }
    data += n;
    size -= static_cast<std::size_t>(n);
  }
}

/// One per process, never destroyed: static destructors and detached threads may still log.
class Logger {
 public:
  Logger()
      : level_(level_from_environment()),
        local_memory_(std::make_unique<std::byte[]>(LogRing::bytes_for(kLocalCapacity))) {
    LogRing::format(local_memory_.get(), kLocalCapacity);
    local_ = LogRing(local_memory_.get());
    // A fork while another thread holds either lock would leave the child's copy held forever.
    ::pthread_atfork(&Logger::before_fork, &Logger::after_fork, &Logger::after_fork);
  }

  std::atomic<LogLevel>& level() noexcept { return level_; }

  void push(const LogEntry& entry) noexcept {
    logged_.fetch_add(1, std::memory_order_relaxed);
    ensure_started();
    local_.push(entry);
    if (shared_ready_.load(std::memory_order_acquire)) shared_.push(entry);
    if (exiting_.load(std::memory_order_relaxed)) flush();
  }

  void ensure_started() noexcept {
    if (writer_pid_.load(std::memory_order_acquire) == this_pid()) return;
    start();
  }

  void flush() noexcept {
    const std::uint64_t target = local_.next_ticket();
    for (int attempt = 0; attempt < kFlushAttempts; ++attempt) {
      {
        std::lock_guard lock(drain_mutex_);
        drain();
        if (printed_ >= target) return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  log::Stats stats() const noexcept {
    return {logged_.load(std::memory_order_relaxed),
            local_.dropped() + lost_.load(std::memory_order_relaxed)};
  }

 private:
  static void before_fork() noexcept;
  static void after_fork() noexcept;

  void start() noexcept {
    std::lock_guard start_lock(start_mutex_);
    const std::uint32_t pid = this_pid();
    if (writer_pid_.load(std::memory_order_acquire) == pid) return;
    if (writer_pid_.load(std::memory_order_relaxed) != 0) {
      // A forked child: the lines queued before the fork are its parent's to print.
      std::lock_guard drain_lock(drain_mutex_);
      printed_ = local_.next_ticket();
    }
    if (!shared_attempted_) {
      shared_attempted_ = true;
      try {
        shared_ = open_shared_log_ring({});
        shared_ready_.store(true, std::memory_order_release);
      } catch (const std::exception& e) {
        char note[512];
        const int n =
            std::snprintf(note, sizeof(note), "[horus] logging to stderr only: %s\n", e.what());
        write_all(note, static_cast<std::size_t>(std::clamp(n, 0, 511)));
      }
    }
    try {
      std::thread([this] {
        for (;;) {
          std::this_thread::sleep_for(kWriterPeriod);
          std::lock_guard lock(drain_mutex_);
          drain();
        }
      }).detach();
    } catch (const std::system_error&) {
      // No thread to spare: every line is written by the caller instead.
      exiting_.store(true, std::memory_order_relaxed);
    }
    if (!exit_hook_registered_) {
      exit_hook_registered_ = true;
      std::atexit([] { logger_at_exit(); });
    }
    writer_pid_.store(pid, std::memory_order_release);
  }

  static void logger_at_exit() noexcept;

  // Writes the lines queued since the last pass (caller holds drain_mutex_).
  void drain() noexcept {
    const std::uint64_t next = local_.next_ticket();
    const std::uint64_t capacity = local_.capacity();
    if (next - printed_ > capacity) {
      lost_.fetch_add(next - capacity - printed_, std::memory_order_relaxed);
      printed_ = next - capacity;
    }
    char batch[8192];
    std::size_t used = 0;
    constexpr std::size_t kLineRoom = 640;
    LogEntry entry{};
    while (printed_ < next) {
      const LogRing::Read result = local_.read(printed_, entry);
      if (result == LogRing::Read::Pending) {
        if (stalled_ticket_ != printed_) {
          stalled_ticket_ = printed_;
          stall_passes_ = 0;
        }
        if (++stall_passes_ < kStallPasses) break;
      }
      if (result == LogRing::Read::Ready) {
        if (used + kLineRoom > sizeof(batch)) {
          write_all(batch, used);
          used = 0;
        }
        used += format_log_entry(entry, batch + used, kLineRoom - 1);
        batch[used++] = '\n';
      } else {
        lost_.fetch_add(1, std::memory_order_relaxed);
      }
      ++printed_;
    }
    write_all(batch, used);
  }

  std::atomic<LogLevel> level_;
  std::unique_ptr<std::byte[]> local_memory_;
  LogRing local_;
  LogRing shared_;
  std::atomic<bool> shared_ready_{false};
  std::atomic<std::uint64_t> logged_{0};
  std::atomic<std::uint64_t> lost_{0};
  std::atomic<std::uint32_t> writer_pid_{0};
  std::atomic<bool> exiting_{false};

  std::mutex start_mutex_;  // never taken by a line once the writer runs
  bool shared_attempted_ = false;
  bool exit_hook_registered_ = false;

  std::mutex drain_mutex_;  // the writer thread and flush(); never taken by a line
  std::uint64_t printed_ = 0;
  std::uint64_t stalled_ticket_ = UINT64_MAX;
  int stall_passes_ = 0;
};

Logger& logger() noexcept {
  // Built in static storage and never destroyed. Its construction allocates the ring once; out
  // of memory there, a process cannot log at all and terminates.
  alignas(Logger) static std::byte storage[sizeof(Logger)];
  static Logger* const instance = ::new (storage) Logger();
  return *instance;
}

void Logger::before_fork() noexcept {
  logger().start_mutex_.lock();
  logger().drain_mutex_.lock();
}

void Logger::after_fork() noexcept {
  logger().drain_mutex_.unlock();
  logger().start_mutex_.unlock();
}

void Logger::logger_at_exit() noexcept {
  Logger& self = logger();
  self.exiting_.store(true, std::memory_order_relaxed);
  self.flush();
}

void fill_entry(LogEntry& entry, LogLevel level, std::string_view source) noexcept {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  entry.wall_time_ns = static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
  entry.pid = this_pid();
  entry.level = static_cast<std::uint8_t>(level);
  if (source.empty()) source = "-";
  entry.source_size = static_cast<std::uint8_t>(std::min(source.size(), kMaxLogSource));
  std::memcpy(entry.source, source.data(), entry.source_size);
}

thread_local std::string_view thread_source;

std::string_view current_source() noexcept {
  const TickContext* context = current_tick_context();
  return context != nullptr ? context->node_name : thread_source;
}

}  // namespace

void prepare_logging() noexcept { logger().ensure_started(); }

std::string_view exchange_thread_log_source(std::string_view source) noexcept {
  return std::exchange(thread_source, source);
}

void vlog_as(LogLevel level, std::string_view source, const char* format, va_list args) noexcept {
  if (!log::enabled(level)) return;
  LogEntry entry;
  fill_entry(entry, level, source);
  char text[kMaxLogText + 1];
  const int n = std::vsnprintf(text, sizeof(text), format, args);
  entry.text_size = static_cast<std::uint16_t>(std::clamp<int>(n, 0, kMaxLogText));
  std::memcpy(entry.text, text, entry.text_size);
  logger().push(entry);
}

void log_as(LogLevel level, std::string_view source, const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  vlog_as(level, source, format, args);
  va_end(args);
}

}  // namespace detail

std::string_view to_string(LogLevel level) noexcept {
  switch (level) {
    case LogLevel::Debug:
      return "DEBUG";
    case LogLevel::Info:
      return "INFO";
    case LogLevel::Warn:
      return "WARN";
    case LogLevel::Error:
      return "ERROR";
  }
  return "?";
}

namespace log {

void set_level(LogLevel level) noexcept {
  detail::logger().level().store(level, std::memory_order_relaxed);
}

LogLevel level() noexcept { return detail::logger().level().load(std::memory_order_relaxed); }

bool enabled(LogLevel level) noexcept { return level >= log::level(); }

#define HORUS_DEFINE_LOG_FUNCTION(function, level_value)                  \
  void function(const char* format, ...) noexcept {                       \
    va_list args;                                                         \
    va_start(args, format);                                               \
    detail::vlog_as(level_value, detail::current_source(), format, args); \
    va_end(args);                                                         \
  }
HORUS_DEFINE_LOG_FUNCTION(debug, LogLevel::Debug)
HORUS_DEFINE_LOG_FUNCTION(info, LogLevel::Info)
HORUS_DEFINE_LOG_FUNCTION(warn, LogLevel::Warn)
HORUS_DEFINE_LOG_FUNCTION(error, LogLevel::Error)
#undef HORUS_DEFINE_LOG_FUNCTION

void emit(LogLevel level, std::string_view source, std::string_view message) noexcept {
  if (!enabled(level)) return;
  detail::LogEntry entry;
  detail::fill_entry(entry, level, source);
  entry.text_size = static_cast<std::uint16_t>(std::min(message.size(), kMaxLogText));
  std::memcpy(entry.text, message.data(), entry.text_size);
  detail::logger().push(entry);
}

std::string_view current_node() noexcept { return detail::current_source(); }

void flush() noexcept { detail::logger().flush(); }

Stats stats() noexcept { return detail::logger().stats(); }

}  // namespace log
}  // namespace horus
