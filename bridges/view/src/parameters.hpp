// The namespace's parameters as the live view offers them (the Foxglove protocol's `parameters`
// and `parametersSubscribe` capabilities): each node's store read through horus::ParamStoreReader,
// every parameter named "NODE.PARAMETER", its value as a JSON value (numbers, true/false, strings,
// an enum by its enumerator's name, lists), and writes made through horus::set_param on a worker
// thread of their own, since a write waits for the owning node's answer.
#pragma once

#include <capnp/compat/json.capnp.h>
#include <kj/async.h>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "horus/params.hpp"

namespace horus::view {

/// "NODE.PARAMETER" split at its last dot (a node name may hold dots, a parameter name never
/// does); none when there is no dot.
std::optional<std::pair<std::string, std::string>> split_parameter_name(std::string_view name);

/// The protocol's name of a parameter: "NODE.PARAMETER".
std::string parameter_name(const ParamInfo& info);

/// A parameter as an entry of parameterValues: {"name", "value", "type"?}, with the protocol's
/// type hint "float64" / "float64_array" for f32 and f64 (so 1.0 stays a float to a client that
/// writes it back).
std::string parameter_entry(const ParamInfo& info);

/// A client's JSON value as the MessagePack VALUE bytes set_param takes: a whole number as an
/// integer (the value's check then says whether the parameter takes it), any other number as
/// f64, true/false, a string, a list of those. Throws horus::view::ProtocolError for anything
/// else (an object, null).
std::string parameter_value(capnp::json::Value::Reader value);

/// The parameter stores of one namespace, opened as they appear; used on the event loop only.
class ParameterStores {
 public:
  explicit ParameterStores(std::string namespace_name);

  /// Opens the stores that appeared, forgets those removed, and opens again those whose owner
  /// ended (a restart with other declarations puts a new file in the old one's place).
  void discover();
  /// Every parameter, by node name then in declaration order.
  std::vector<ParamInfo> list() const;
  /// The parameter called "NODE.PARAMETER", when there is one.
  std::optional<ParamInfo> find(std::string_view name) const;
  /// The parameters whose value changed since the last call: each store's change count is one
  /// load; only the stores whose count moved have their records read.
  std::vector<ParamInfo> changed();

 private:
  struct Store {
    ParamStoreReader reader;
    std::uint64_t changes_seen = 0;
    /// Each parameter's version when last looked at.
    std::map<std::string, std::uint64_t> versions;
  };
  /// Opens (or opens again) `node`'s store; throws as ParamStoreReader does.
  void open(const std::string& node);

  std::string namespace_;
  std::map<std::string, Store> stores_;
};

/// Writes parameters on a thread of its own, one request after the other; each request's
/// outcome resolves on the event loop that asked.
class ParameterWriter {
 public:
  /// One write: the parameter's node and name, its value (MessagePack VALUE).
  struct Write {
    std::string node;
    std::string name;
    std::string value;
  };
  /// A write's outcome: the result, or why it could not be tried (a ParamError's text).
  struct Outcome {
    ParamSetResult result;
    std::string failure;
  };

  explicit ParameterWriter(std::string namespace_name);
  ~ParameterWriter();
  ParameterWriter(const ParameterWriter&) = delete;
  ParameterWriter& operator=(const ParameterWriter&) = delete;

  /// The outcomes of `writes`, in order, once all are done. `source`: who writes, as the
  /// owner's on_param_change() is told ("view:PEER").
  kj::Promise<std::vector<Outcome>> write(std::vector<Write> writes, std::string source);

 private:
  void run();

  std::string namespace_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  /// Last: started once the rest is ready, joined first.
  std::thread thread_;
};

}  // namespace horus::view
