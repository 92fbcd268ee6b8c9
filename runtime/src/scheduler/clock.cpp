#include "horus/clock.hpp"

#include <limits>
#include <random>

#include "tick_context.hpp"

namespace horus {
namespace detail {

TickContext*& current_tick_context() noexcept {
  thread_local TickContext* context = nullptr;
  return context;
}

namespace {

Rng& thread_rng() noexcept {
  thread_local Rng rng{[] {
    std::random_device device;
    return (static_cast<std::uint64_t>(device()) << 32) ^ device();
  }()};
  return rng;
}

}  // namespace
}  // namespace detail

using detail::current_tick_context;

std::chrono::nanoseconds now() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  if (ctx != nullptr && ctx->deterministic) {
    return std::chrono::nanoseconds(ctx->sim_now_ns);
  }
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

std::uint64_t timestamp_now() noexcept { return static_cast<std::uint64_t>(now().count()); }

std::chrono::nanoseconds dt() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  return std::chrono::nanoseconds(ctx != nullptr ? ctx->dt_ns : 0);
}

std::chrono::nanoseconds elapsed() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  if (ctx == nullptr) return std::chrono::nanoseconds(0);
  if (ctx->deterministic) return std::chrono::nanoseconds(ctx->sim_now_ns);
  return std::chrono::nanoseconds(detail::monotonic_ns() - ctx->start_ns);
}

std::uint64_t tick_index() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  return ctx != nullptr ? ctx->tick_index : 0;
}

std::chrono::nanoseconds budget_remaining() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  if (ctx == nullptr || ctx->budget_ns <= 0) return std::chrono::nanoseconds::max();
  if (ctx->deterministic) return std::chrono::nanoseconds(ctx->budget_ns);
  return std::chrono::nanoseconds(ctx->budget_ns - (detail::monotonic_ns() - ctx->tick_start_ns));
}

std::chrono::nanoseconds lateness() noexcept {
  const detail::TickContext* ctx = current_tick_context();
  if (ctx == nullptr || ctx->deterministic) return std::chrono::nanoseconds(0);
  return std::chrono::nanoseconds(ctx->tick_start_ns - ctx->release_ns);
}

double rng_float() noexcept {
  detail::TickContext* ctx = current_tick_context();
  if (ctx != nullptr && ctx->rng != nullptr) return ctx->rng->next_double();
  return detail::thread_rng().next_double();
}

}  // namespace horus
