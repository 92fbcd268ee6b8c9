// horus::ServiceResult<T>: the outcome of a service call, a value or a ServiceError. C++20 has no
// std::expected, and the call path reports failures as values, never as exceptions.
#pragma once

#include <concepts>
#include <type_traits>
#include <utility>
#include <variant>

#include "horus/error.hpp"
#include "horus/service_error.hpp"

namespace horus {

template <class T>
class ServiceResult {
  static_assert(!std::is_reference_v<T> && !std::same_as<std::remove_cv_t<T>, ServiceError>,
                "ServiceResult holds a value type other than ServiceError");

 public:
  using value_type = T;

  /// A value: anything T is constructible from (a response, std::nullopt for an optional).
  /// The constraint excludes ServiceResult itself, so copies and moves are not hidden.
  // NOLINTBEGIN(bugprone-forwarding-reference-overload)
  template <class U = T>
  requires(std::constructible_from<T, U&&> &&
           !std::same_as<std::remove_cvref_t<U>, ServiceResult> &&
           !std::same_as<std::remove_cvref_t<U>, ServiceError>) ServiceResult(U&& value)
      : state_(std::in_place_index<0>, std::forward<U>(value)) {}
  // NOLINTEND(bugprone-forwarding-reference-overload)
  ServiceResult(ServiceError error) : state_(std::in_place_index<1>, std::move(error)) {}

  bool has_value() const noexcept { return state_.index() == 0; }
  explicit operator bool() const noexcept { return has_value(); }

  /// The value; throws horus::Error when the result is an error (a misuse: test has_value()).
  T& value() & { return checked(*this); }
  const T& value() const& { return checked(*this); }
  T&& value() && { return std::move(checked(*this)); }

  /// Unchecked access, like std::optional's: only after has_value().
  T& operator*() & noexcept { return *std::get_if<0>(&state_); }
  const T& operator*() const& noexcept { return *std::get_if<0>(&state_); }
  T* operator->() noexcept { return std::get_if<0>(&state_); }
  const T* operator->() const noexcept { return std::get_if<0>(&state_); }

  /// The error; throws horus::Error when the result is a value.
  const ServiceError& error() const {
    if (const ServiceError* error = std::get_if<1>(&state_)) {
      return *error;
    }
    throw Error("ServiceResult::error() called on a result that holds a value");
  }

  template <class U>
  T value_or(U&& fallback) const& {
    return has_value() ? **this : static_cast<T>(std::forward<U>(fallback));
  }

 private:
  template <class Self>
  static auto& checked(Self& self) {
    if (!self.has_value()) {
      throw Error("ServiceResult::value() called on an error: " +
                  std::get_if<1>(&self.state_)->to_string());
    }
    return *std::get_if<0>(&self.state_);
  }

  std::variant<T, ServiceError> state_;
};

}  // namespace horus
