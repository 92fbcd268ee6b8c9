// horus::TopicLog: what a verbose topic handle (TopicOptions::verbose, Topic::set_verbose) writes
// to the runtime's log (horus/log.hpp, so `horus log` and the monitor show it): one INFO line per
// message sent or received, "<topic> send: <summary>" / "<topic> recv: <summary>", in the name
// of the node whose callback runs.
//
// At most kLinesPerSecond lines a second per handle: a 1 kHz topic cannot flood the log's ring.
// Messages beyond are not summarised at all (the limit is checked first) but counted, and the
// count goes out as "<topic>: <n> lines suppressed (...)" with the next line let through, or when
// the handle is dropped or made quiet. A summary is formatted into a buffer on the stack; only a
// generated message's log_summary(), which returns a std::string, allocates, and only for lines let
// through. Public so that a binding's verbose handle (Python's horus.Topic) writes the same lines
// under the same limit, with a summary made in its own language.
#pragma once

#include <algorithm>
#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

#include "horus/log_summary.hpp"
#include "horus/type_info.hpp"

namespace horus {

enum class TopicLogDirection : std::uint8_t { Send, Recv };

namespace detail {

/// Writes into a fixed buffer, cutting what does not fit.
class SummaryWriter {
 public:
  SummaryWriter(char* buffer, std::size_t size) noexcept : buffer_(buffer), size_(size) {}

  void text(std::string_view s) noexcept;
  void number(double value) noexcept;
  void number(long long value) noexcept;
  void number(unsigned long long value) noexcept;
  std::string_view view() const noexcept { return {buffer_, used_}; }

 private:
  char* buffer_;
  std::size_t size_;
  std::size_t used_ = 0;
};

/// The summary of a plain value by the rules of horus/log_summary.hpp, as horus::log_summary()
/// and Python's plain values print it, into a fixed buffer instead of a std::string.
template <class T>
void summarize_value(SummaryWriter& out, const T& value) noexcept {
  if constexpr (std::same_as<T, bool>) {
    out.text(value ? "true" : "false");
  } else if constexpr (std::is_floating_point_v<T>) {
    out.number(static_cast<double>(value));
  } else if constexpr (std::is_integral_v<T> && std::is_signed_v<T>) {
    out.number(static_cast<long long>(value));
  } else if constexpr (std::is_integral_v<T>) {
    out.number(static_cast<unsigned long long>(value));
  } else if constexpr (std::convertible_to<const T&, std::string_view>) {
    out.text("\"");
    out.text(std::string_view(value));
    out.text("\"");
  } else {
    using Element = typename T::value_type;
    if constexpr (std::same_as<Element, std::uint8_t>) {
      out.text("<");
      out.number(static_cast<unsigned long long>(value.size()));
      out.text(" bytes>");
      return;
    }
    constexpr bool kNumbers = std::is_arithmetic_v<Element> && !std::same_as<Element, bool>;
    if (value.size() == 0) {
      out.text("[]");
      return;
    }
    if (value.size() > (kNumbers ? summary::kMaxNumbersShown : summary::kMaxElementsShown)) {
      out.text("[");
      out.number(static_cast<unsigned long long>(value.size()));
      out.text(" x ");
      out.text(TypeInfo<Element>::name);
      if constexpr (kNumbers) {
        const auto [lo, hi] = std::minmax_element(value.begin(), value.end());
        out.text(", min ");
        summarize_value(out, *lo);
        out.text(", max ");
        summarize_value(out, *hi);
      }
      out.text("]");
      return;
    }
    out.text("[");
    bool first = true;
    for (const Element& element : value) {
      if (!first) out.text(", ");
      first = false;
      summarize_value(out, element);
    }
    out.text("]");
  }
}

}  // namespace detail

class TopicLog {
 public:
  static constexpr std::uint32_t kLinesPerSecond = 10;

  explicit TopicLog(std::string_view topic);
  ~TopicLog();
  TopicLog(const TopicLog&) = delete;
  TopicLog& operator=(const TopicLog&) = delete;

  /// Whether one more message may have its line now; if not, it is counted as suppressed.
  bool admit() noexcept;
  /// The line of one admitted message.
  void write(TopicLogDirection direction, std::string_view summary) noexcept;

  /// admit(), then the summary of `msg` (its log_summary() for a message) and write().
  template <class T>
  void message(TopicLogDirection direction, const T& msg) noexcept {
    if (!admit()) return;
    std::array<char, kMaxSummary> buffer;
    detail::SummaryWriter out(buffer.data(), buffer.size());
    summarize(out, msg);
    write(direction, out.view());
  }

  /// The summary of `msg` into `out`.
  template <class T>
  static void summarize(detail::SummaryWriter& out, const T& msg) noexcept {
    if constexpr (requires { msg.log_summary(); }) {
      try {
        out.text(msg.log_summary());
      } catch (...) {
        out.text("(no memory for the summary)");
      }
    } else if constexpr (Message<T>) {
      out.text(TypeInfo<T>::name);
    } else {
      detail::summarize_value(out, msg);
    }
  }

  /// Longest summary kept: the rest of the log line's text is the topic's name and direction.
  static constexpr std::size_t kMaxSummary = 384;

 private:
  void report_suppressed() noexcept;

  std::string topic_;
  std::int64_t window_start_ns_ = 0;
  std::uint32_t lines_in_window_ = 0;
  std::uint64_t suppressed_ = 0;
};

}  // namespace horus
