// horus::Error: the one exception type of set-up and configuration failures.
#pragma once

#include <stdexcept>
#include <string>

namespace horus {

/// Thrown by set-up and configuration calls (opening a topic with the wrong type, a scheduler
/// misconfiguration, decoding bytes that are not a valid message). Hot paths never throw.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bytes that do not decode as the requested type: wrong length, truncated or mistyped MessagePack.
class DecodeError : public Error {
 public:
  using Error::Error;
};

}  // namespace horus
