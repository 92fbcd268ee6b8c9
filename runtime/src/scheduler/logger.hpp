// What the scheduler (and the rest of the runtime) uses of the logger beyond the public API.
#pragma once

#include <cstdarg>
#include <string_view>

#include "horus/log.hpp"

namespace horus::detail {

/// Opens the namespace's shared ring and starts the stderr writer now, so that the first line a
/// node logs from a tick does not pay for it. Idempotent; a forked child starts its own writer.
void prepare_logging() noexcept;

/// A printf-style line with an explicit source (the scheduler's lines use "@<name>").
void log_as(LogLevel level, std::string_view source, const char* format, ...) noexcept
    __attribute__((format(printf, 3, 4)));
void vlog_as(LogLevel level, std::string_view source, const char* format, va_list args) noexcept;

}  // namespace horus::detail
