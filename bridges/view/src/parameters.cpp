// The live view's parameters: the stores read, values as JSON and back, and the writer thread
// (parameters.hpp).
#include "parameters.hpp"

#include <cmath>
#include <cstdio>
#include <set>

#include "horus/json_string.hpp"
#include "horus/msgpack.hpp"
#include "protocol.hpp"

namespace horus::view {

namespace {

bool is_float(const TypeRef& type) {
  return type.kind == TypeRef::Kind::Primitive &&
         (type.primitive == Primitive::F32 || type.primitive == Primitive::F64);
}

void pack_value(capnp::json::Value::Reader value, msgpack::packer<msgpack::sbuffer>& packer) {
  switch (value.which()) {
    case capnp::json::Value::BOOLEAN:
      if (value.getBoolean()) {
        packer.pack_true();
      } else {
        packer.pack_false();
      }
      return;
    case capnp::json::Value::NUMBER: {
      const double number = value.getNumber();
      // 2^63: beyond it a whole double is no int64.
      constexpr double kInt64Limit = 9223372036854775808.0;
      if (std::isfinite(number) && number == std::trunc(number) && number < kInt64Limit &&
          number >= -kInt64Limit) {
        if (number < 0) {
          packer.pack_int64(static_cast<std::int64_t>(number));
        } else {
          packer.pack_uint64(static_cast<std::uint64_t>(number));
        }
      } else {
        packer.pack_double(number);
      }
      return;
    }
    case capnp::json::Value::STRING: {
      const capnp::Text::Reader text = value.getString();
      packer.pack_str(static_cast<std::uint32_t>(text.size()));
      packer.pack_str_body(text.cStr(), static_cast<std::uint32_t>(text.size()));
      return;
    }
    case capnp::json::Value::ARRAY: {
      const auto items = value.getArray();
      packer.pack_array(items.size());
      for (const auto item : items) pack_value(item, packer);
      return;
    }
    default:
      throw ProtocolError(
          "a parameter's value is a number, true/false, a string or a list of those");
  }
}

}  // namespace

std::optional<std::pair<std::string, std::string>> split_parameter_name(std::string_view name) {
  const std::size_t dot = name.rfind('.');
  if (dot == std::string_view::npos || dot == 0 || dot + 1 == name.size()) return std::nullopt;
  return std::make_pair(std::string(name.substr(0, dot)), std::string(name.substr(dot + 1)));
}

std::string parameter_name(const ParamInfo& info) {
  return info.node + "." + info.declaration.name;
}

std::string parameter_entry(const ParamInfo& info) {
  std::string value;
  try {
    value = param_value_json(info.value, &info.declaration);
  } catch (const ParamError&) {
    value = "null";  // the store's reader checked it: not reached
  }
  std::string entry = "{\"name\":" + json_string(parameter_name(info)) + ",\"value\":" + value;
  const TypeRef& type = info.declaration.type;
  if (is_float(type)) {
    entry += ",\"type\":\"float64\"";
  } else if (type.kind == TypeRef::Kind::Array && type.element && is_float(*type.element)) {
    entry += ",\"type\":\"float64_array\"";
  }
  return entry + "}";
}

std::string parameter_value(capnp::json::Value::Reader value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  pack_value(value, packer);
  return std::string(buffer.data(), buffer.size());
}

// ---------------------------------------------------------------------------------------------

ParameterStores::ParameterStores(std::string namespace_name)
    : namespace_(std::move(namespace_name)) {}

void ParameterStores::open(const std::string& node) {
  Store store{ParamStoreReader(node, namespace_), 0, {}};
  const auto before = stores_.find(node);
  if (before == stores_.end()) {
    store.changes_seen = store.reader.change_count();
    for (const ParamInfo& info : store.reader.list()) {
      store.versions[info.declaration.name] = info.version;
    }
    stores_.emplace(node, std::move(store));
    return;
  }
  // Opened again (its owner ended, and may have started anew): what changed since it was last
  // looked at is told at the next changed().
  store.versions = std::move(before->second.versions);
  store.changes_seen = ~store.reader.change_count();
  before->second = std::move(store);
}

void ParameterStores::discover() {
  std::vector<std::string> nodes;
  try {
    nodes = param_nodes(namespace_);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "horus-view: the parameter stores are not read: %s\n", error.what());
    return;
  }
  const std::set<std::string> present(nodes.begin(), nodes.end());
  std::erase_if(stores_, [&](const auto& entry) { return present.count(entry.first) == 0; });
  for (const std::string& node : nodes) {
    const auto it = stores_.find(node);
    if (it != stores_.end() && it->second.reader.owner_alive()) continue;
    try {
      open(node);
    } catch (const std::exception&) {
      // A store being replaced, or one that cannot be trusted: left out until it reads.
      stores_.erase(node);
    }
  }
}

std::vector<ParamInfo> ParameterStores::list() const {
  std::vector<ParamInfo> all;
  for (const auto& [node, store] : stores_) {
    std::vector<ParamInfo> params = store.reader.list();
    all.insert(all.end(), std::make_move_iterator(params.begin()),
               std::make_move_iterator(params.end()));
  }
  return all;
}

std::optional<ParamInfo> ParameterStores::find(std::string_view name) const {
  const auto split = split_parameter_name(name);
  if (!split) return std::nullopt;
  const auto store = stores_.find(split->first);
  if (store == stores_.end()) return std::nullopt;
  try {
    return store->second.reader.get(split->second);
  } catch (const ParamError&) {
    return std::nullopt;
  }
}

std::vector<ParamInfo> ParameterStores::changed() {
  std::vector<ParamInfo> changed;
  for (auto& [node, store] : stores_) {
    const std::uint64_t changes = store.reader.change_count();
    if (changes == store.changes_seen) continue;
    store.changes_seen = changes;
    for (ParamInfo& info : store.reader.list()) {
      std::uint64_t& seen = store.versions[info.declaration.name];
      if (info.version == seen) continue;
      seen = info.version;
      changed.push_back(std::move(info));
    }
  }
  return changed;
}

// ---------------------------------------------------------------------------------------------

ParameterWriter::ParameterWriter(std::string namespace_name)
    : namespace_(std::move(namespace_name)), thread_([this] { run(); }) {}

ParameterWriter::~ParameterWriter() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

void ParameterWriter::run() {
  std::unique_lock lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
    if (stopping_) return;
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    lock.unlock();
    job();
    lock.lock();
  }
}

kj::Promise<std::vector<ParameterWriter::Outcome>> ParameterWriter::write(std::vector<Write> writes,
                                                                          std::string source) {
  // The outcomes travel beside a void promise (kj's value-carrying one trips GCC's
  // maybe-uninitialized on a vector); the job owns its fulfiller, so a loop that stopped waiting
  // is simply not told.
  auto done = kj::newPromiseAndCrossThreadFulfiller<void>();
  auto fulfiller =
      std::make_shared<kj::Own<kj::CrossThreadPromiseFulfiller<void>>>(kj::mv(done.fulfiller));
  auto outcomes = std::make_shared<std::vector<Outcome>>();
  ParamSetOptions options;
  options.namespace_name = namespace_;
  options.source = std::move(source);
  {
    const std::lock_guard lock(mutex_);
    jobs_.emplace_back([writes = std::move(writes), options, fulfiller, outcomes] {
      for (const Write& write : writes) {
        Outcome outcome;
        try {
          outcome.result = set_param(write.node, write.name, write.value, options);
        } catch (const std::exception& error) {
          outcome.failure = error.what();
        }
        outcomes->push_back(std::move(outcome));
      }
      (*fulfiller)->fulfill();
    });
  }
  wake_.notify_one();
  return done.promise.then([outcomes] { return std::move(*outcomes); });
}

}  // namespace horus::view
