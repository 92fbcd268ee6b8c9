#include "horus/topic_log.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>

#include "horus/log.hpp"

namespace horus {
namespace {

std::int64_t coarse_now_ns() noexcept {
  // The coarse clock is read from the vDSO without a counter read: cheap enough for every
  // message of a 1 kHz topic, and a one-second window needs no finer resolution.
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC_COARSE, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

constexpr std::int64_t kWindowNs = 1'000'000'000;

}  // namespace

namespace detail {

void SummaryWriter::text(std::string_view s) noexcept {
  const std::size_t n = std::min(s.size(), size_ - used_);
  std::memcpy(buffer_ + used_, s.data(), n);
  used_ += n;
}

void SummaryWriter::number(double value) noexcept {
  char digits[32];
  const int n = std::snprintf(digits, sizeof digits, "%g", value);
  text({digits, static_cast<std::size_t>(std::max(n, 0))});
}

void SummaryWriter::number(long long value) noexcept {
  char digits[24];
  const int n = std::snprintf(digits, sizeof digits, "%lld", value);
  text({digits, static_cast<std::size_t>(std::max(n, 0))});
}

void SummaryWriter::number(unsigned long long value) noexcept {
  char digits[24];
  const int n = std::snprintf(digits, sizeof digits, "%llu", value);
  text({digits, static_cast<std::size_t>(std::max(n, 0))});
}

}  // namespace detail

TopicLog::TopicLog(std::string_view topic) : topic_(topic) {}

TopicLog::~TopicLog() { report_suppressed(); }

bool TopicLog::admit() noexcept {
  const std::int64_t now = coarse_now_ns();
  if (now - window_start_ns_ >= kWindowNs) {
    report_suppressed();
    window_start_ns_ = now;
    lines_in_window_ = 0;
  }
  if (lines_in_window_ < kLinesPerSecond) {
    ++lines_in_window_;
    return true;
  }
  ++suppressed_;
  return false;
}

void TopicLog::write(TopicLogDirection direction, std::string_view summary) noexcept {
  log::info("%s %s: %.*s", topic_.c_str(), direction == TopicLogDirection::Send ? "send" : "recv",
            static_cast<int>(summary.size()), summary.data());
}

void TopicLog::report_suppressed() noexcept {
  if (suppressed_ == 0) return;
  log::info("%s: %llu lines suppressed (a verbose topic logs at most %u lines a second)",
            topic_.c_str(), static_cast<unsigned long long>(suppressed_), kLinesPerSecond);
  suppressed_ = 0;
}

}  // namespace horus
