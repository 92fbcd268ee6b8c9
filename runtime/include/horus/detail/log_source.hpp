// The source of the lines a thread logs outside node callbacks: a runtime thread that works for a
// node (a service server's) logs in that node's name instead of "-".
#pragma once

#include <string_view>

namespace horus::detail {

/// Sets what the calling thread's lines carry outside node callbacks ("" means "-") and returns
/// the previous source. The characters must outlive their use on the thread.
std::string_view exchange_thread_log_source(std::string_view source) noexcept;

}  // namespace horus::detail
