// Reads back the JSON records the runtime writes itself (a recording's "/horus/params" and
// "/horus/frames" channels), field by field in the order they were written: a record in any other
// shape is refused rather than guessed at.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

namespace horus::detail {

class JsonRecordCursor {
 public:
  explicit JsonRecordCursor(std::string_view text) : text_(text) {}

  /// Consumes `literal` when the text continues with it.
  bool take(std::string_view literal) {
    if (text_.substr(at_, literal.size()) != literal) return false;
    at_ += literal.size();
    return true;
  }
  std::optional<std::uint64_t> number() {
    std::uint64_t value = 0;
    const std::size_t first = at_;
    while (at_ < text_.size() && text_[at_] >= '0' && text_[at_] <= '9') {
      value = value * 10 + static_cast<std::uint64_t>(text_[at_++] - '0');
    }
    if (at_ == first) return std::nullopt;
    return value;
  }
  /// A JSON number as "%.17g" writes a double.
  std::optional<double> real() {
    const std::size_t first = at_;
    while (at_ < text_.size() &&
           std::string_view("+-.0123456789eE").find(text_[at_]) != std::string_view::npos) {
      ++at_;
    }
    const std::string digits(text_.substr(first, at_ - first));
    char* end = nullptr;
    const double value = std::strtod(digits.c_str(), &end);
    if (digits.empty() || end != digits.c_str() + digits.size()) return std::nullopt;
    return value;
  }
  /// A JSON string literal as json_string() writes it.
  std::optional<std::string> literal() {
    if (!take("\"")) return std::nullopt;
    std::string out;
    while (at_ < text_.size()) {
      const char c = text_[at_++];
      if (c == '"') return out;
      if (c != '\\') {
        out += c;
      } else if (at_ < text_.size() && text_[at_] == 'u' && at_ + 5 <= text_.size()) {
        out += static_cast<char>(
            std::strtoul(std::string(text_.substr(at_ + 1, 4)).c_str(), nullptr, 16));
        at_ += 5;
      } else if (at_ < text_.size()) {
        out += text_[at_++];
      }
    }
    return std::nullopt;
  }
  bool at_end() const noexcept { return at_ == text_.size(); }

 private:
  std::string_view text_;
  std::size_t at_ = 0;
};

}  // namespace horus::detail
