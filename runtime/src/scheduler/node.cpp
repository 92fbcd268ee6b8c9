#include "horus/node.hpp"

#include <cxxabi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <typeinfo>

#include "horus/log.hpp"
#include "logger.hpp"
#include "scheduler_impl.hpp"

namespace horus {
namespace {

// "robot::sensors::ImuReader" -> "ImuReader", leaving template arguments intact:
// "robot::Filter<robot::Imu>" -> "Filter<robot::Imu>".
std::string strip_namespaces(std::string_view qualified) {
  int depth = 0;
  std::size_t start = 0;
  for (std::size_t i = 0; i < qualified.size(); ++i) {
    const char c = qualified[i];
    if (c == '<') {
      ++depth;
    } else if (c == '>') {
      --depth;
    } else if (depth == 0 && c == ':' && i + 1 < qualified.size() && qualified[i + 1] == ':') {
      start = i + 2;
    }
  }
  return std::string(qualified.substr(start));
}

}  // namespace

std::string_view Node::name() const {
  if (default_name_.empty()) {
    const char* mangled = typeid(*this).name();
    int status = 0;
    std::unique_ptr<char, decltype(&std::free)> demangled(
        abi::__cxa_demangle(mangled, nullptr, nullptr, &status), &std::free);
    default_name_ = strip_namespaces(status == 0 && demangled ? demangled.get() : mangled);
  }
  return default_name_;
}

void Node::on_error(std::string_view error) {
  // Inside a callback the line carries the node's name already; elsewhere it is given.
  const std::string_view source = log::current_node().empty() ? name() : log::current_node();
  detail::log_as(LogLevel::Error, source, "Node error: %.*s", static_cast<int>(error.size()),
                 error.data());
}

void Node::request_stop() noexcept {
  if (const auto scheduler = scheduler_.lock()) {
    char reason[96];
    std::snprintf(reason, sizeof(reason), "node '%.*s' called request_stop()",
                  static_cast<int>(std::min<std::size_t>(name().size(), 64)), name().data());
    scheduler->request_stop(reason, false);
  }
}

}  // namespace horus
