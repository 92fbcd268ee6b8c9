// Parameters across the link: the robot's view of its stores for one peer, and the laptop's
// mirrors (remote_params.hpp).
#include "remote_params.hpp"

#include <algorithm>
#include <random>

#include "horus/bridge/topic_policy.hpp"
#include "horus/node.hpp"
#include "link.hpp"

namespace horus::remote {

namespace {

/// A dead node's store is looked at again no more often than this (a restart may replace it).
constexpr auto kReopenInterval = std::chrono::seconds(1);
/// How long a write made here waits for the robot's verdict.
constexpr auto kForwardTimeout = std::chrono::seconds(10);
/// How long the robot waits for a change before answering `params` anyway.
constexpr std::uint32_t kParamsWaitMs = 1000;

std::uint64_t mix(std::uint64_t digest, std::uint64_t value) {
  return (digest ^ value) * 0x100000001b3ULL;
}

std::uint64_t mix(std::uint64_t digest, const std::string& text) {
  for (const char c : text) digest = mix(digest, static_cast<unsigned char>(c));
  return mix(digest, 0xff);
}

/// A robot node's parameters here: writes from `sync_source` are the robot's values, taken as
/// they come; every other write is the robot's owner's to judge.
class MirrorNode final : public Node {
 public:
  using Forward = std::function<ParamSetResult(const std::string& node, const std::string& name,
                                               const std::string& value)>;
  /// `started`: called once the store is open (with what a write while the link was down
  /// persisted in it), before the first tick.
  MirrorNode(std::string name, std::vector<ParamDeclaration> declarations, std::string sync_source,
             Forward forward, std::function<void()> started)
      : name_(std::move(name)),
        sync_source_(std::move(sync_source)),
        forward_(std::move(forward)),
        started_(std::move(started)) {
    for (ParamDeclaration& declaration : declarations) declare_param(std::move(declaration));
  }
  std::string_view name() const override { return name_; }
  void init() override { started_(); }
  void tick() override {}
  ParamVerdict on_param_change(const ParamChange& change) override {
    if (change.source == sync_source_) return ParamVerdict::accept();
    ParamSetResult result = forward_(name_, change.name(), change.value);
    if (result.accepted) return ParamVerdict::accept();
    // The owner here says "node NAME refused: " before the reason already.
    const std::string said_twice = "node " + name_ + " refused: ";
    if (result.reason.starts_with(said_twice)) result.reason.erase(0, said_twice.size());
    return ParamVerdict::refuse("on the robot: " + result.reason);
  }

 private:
  std::string name_;
  std::string sync_source_;
  Forward forward_;
  std::function<void()> started_;
};

}  // namespace

ParamView::ParamView(std::function<bool(const std::string&)> allows, std::string namespace_name)
    : allows_(std::move(allows)), namespace_name_(std::move(namespace_name)) {}

std::uint64_t ParamView::refresh() {
  std::vector<std::string> nodes;
  try {
    nodes = param_nodes(namespace_name_);
  } catch (const std::exception&) {
    // No parameter folder yet: no node has parameters.
  }
  std::erase_if(stores_, [&](const auto& entry) {
    return std::find(nodes.begin(), nodes.end(), entry.first) == nodes.end();
  });
  const auto now = std::chrono::steady_clock::now();
  for (const std::string& node : nodes) {
    Store& store = stores_[node];
    if (store.reader && (store.reader->owner_alive() || now - store.opened < kReopenInterval)) {
      continue;
    }
    store = Store{};
    store.opened = now;
    try {
      store.reader = std::make_unique<ParamStoreReader>(node, namespace_name_);
      TypeDescription description = store.reader->description();
      for (MessageType& message : description.messages) {
        if (message.name != description.root) continue;
        std::erase_if(message.fields,
                      [&](const MessageField& field) { return !allows_(node + "." + field.name); });
        for (const MessageField& field : message.fields) store.names.push_back(field.name);
      }
      store.description = description.encode();
      store.opening = ++openings_;
    } catch (const std::exception&) {
      store.reader.reset();  // being made or replaced: looked at again later
    }
  }
  std::uint64_t digest = 0xcbf29ce484222325ULL;
  for (auto& [node, store] : stores_) {
    store.shown = store.reader && !store.names.empty() && store.reader->owner_alive();
    if (!store.shown) continue;
    digest = mix(mix(mix(digest, node), store.opening), store.reader->change_count());
  }
  return digest;
}

std::size_t ParamView::node_count() const {
  return static_cast<std::size_t>(std::count_if(
      stores_.begin(), stores_.end(), [](const auto& entry) { return entry.second.shown; }));
}

void ParamView::fill(capnp::List<wire::ParamNode>::Builder nodes) const {
  unsigned index = 0;
  for (const auto& [node, store] : stores_) {
    if (!store.shown) continue;
    auto out = nodes[index++];
    out.setNode(node);
    out.setDescription(kj::arrayPtr(reinterpret_cast<const capnp::byte*>(store.description.data()),
                                    store.description.size()));
    std::vector<ParamInfo> values;
    for (ParamInfo& info : store.reader->list()) {
      if (std::find(store.names.begin(), store.names.end(), info.declaration.name) !=
          store.names.end()) {
        values.push_back(std::move(info));
      }
    }
    auto list = out.initValues(static_cast<unsigned>(values.size()));
    for (unsigned i = 0; i < values.size(); ++i) {
      list[i].setName(values[i].declaration.name);
      list[i].setValue(kj::arrayPtr(reinterpret_cast<const capnp::byte*>(values[i].value.data()),
                                    values[i].value.size()));
      list[i].setVersion(values[i].version);
    }
  }
}

struct ParamMirrors::Mirror {
  /// The robot's declarations, as it sent them.
  std::string description;
  /// The robot's values as last seen, by parameter.
  std::map<std::string, std::string> values;
  std::shared_ptr<MirrorNode> node;
  std::unique_ptr<Scheduler> scheduler;
  std::thread thread;

  ~Mirror() {
    if (scheduler) scheduler->stop();
    if (thread.joinable()) thread.join();
  }
};

struct ParamMirrors::Forward {
  std::string node;
  std::string name;
  std::string value;
  bool done = false;
  ParamSetResult result;
};

ParamMirrors::ParamMirrors(wire::Session::Client session, std::vector<std::string> patterns,
                           std::string namespace_name)
    : session_(kj::mv(session)),
      patterns_(std::move(patterns)),
      namespace_name_(std::move(namespace_name)) {
  std::random_device random;
  sync_source_ = "remote sync " + std::to_string(random()) + std::to_string(random());
  sync_thread_ = std::thread([this] { sync_loop(); });
}

ParamMirrors::~ParamMirrors() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  wake_.notify_all();
  mirrors_.clear();  // each scheduler stopped: the stores stay, shown as not running
  sync_thread_.join();
}

void ParamMirrors::taskFailed(kj::Exception&& exception) {
  say("a parameter write to the robot failed: %s", exception.getDescription().cStr());
}

kj::Promise<void> ParamMirrors::run() { return poll().exclusiveJoin(send_forwards()); }

kj::Promise<void> ParamMirrors::poll() {
  auto request = session_.paramsRequest();
  request.setSince(generation_);
  request.setWaitMs(kParamsWaitMs);
  return request.send().then([this](capnp::Response<wire::Session::ParamsResults>&& response) {
    generation_ = response.getGeneration();
    follow(response.getNodes());
    return poll();
  });
}

kj::Promise<void> ParamMirrors::send_forwards() {
  auto waiting = kj::newPromiseAndCrossThreadFulfiller<void>();
  {
    std::lock_guard lock(mutex_);
    if (forwards_.empty()) {
      forwards_waiting_ = kj::mv(waiting.fulfiller);
    } else {
      waiting.fulfiller->fulfill();
    }
  }
  return waiting.promise.then([this] {
    std::deque<std::shared_ptr<Forward>> taken;
    {
      std::lock_guard lock(mutex_);
      taken.swap(forwards_);
    }
    for (const std::shared_ptr<Forward>& forward : taken) {
      auto request = session_.setParamRequest();
      request.setNode(forward->node);
      request.setName(forward->name);
      request.setValue(kj::arrayPtr(reinterpret_cast<const capnp::byte*>(forward->value.data()),
                                    forward->value.size()));
      request.setTimeoutMs(static_cast<std::uint32_t>(
          std::chrono::duration_cast<std::chrono::milliseconds>(kForwardTimeout).count()));
      auto finish = [this, forward](ParamSetResult result) {
        {
          std::lock_guard lock(mutex_);
          forward->result = std::move(result);
          forward->done = true;
        }
        wake_.notify_all();
      };
      sending_.add(request.send().then(
          [finish](capnp::Response<wire::Session::SetParamResults>&& response) {
            finish(ParamSetResult{response.getAccepted(), response.getReason(),
                                  response.getVersion()});
          },
          [finish](kj::Exception&& failure) {
            finish(ParamSetResult{
                false, std::string("the link failed: ") + failure.getDescription().cStr(), 0});
          }));
    }
    return send_forwards();
  });
}

ParamSetResult ParamMirrors::forward(const std::string& node, const std::string& name,
                                     const std::string& value) {
  auto forward = std::make_shared<Forward>(Forward{node, name, value, false, {}});
  std::unique_lock lock(mutex_);
  if (closing_) return ParamSetResult{false, "the link to the robot ended", 0};
  forwards_.push_back(forward);
  unanswered_.push_back(forward);
  if (forwards_waiting_) {
    forwards_waiting_->fulfill();
    forwards_waiting_ = nullptr;
  }
  const bool answered =
      wake_.wait_for(lock, kForwardTimeout, [&] { return forward->done || closing_; });
  std::erase(unanswered_, forward);
  if (forward->done) return forward->result;
  return ParamSetResult{
      false, answered ? "the link to the robot ended" : "the robot did not answer in time", 0};
}

void ParamMirrors::follow(capnp::List<wire::ParamNode>::Reader nodes) {
  std::map<std::string, wire::ParamNode::Reader> shown;
  for (const wire::ParamNode::Reader node : nodes) shown.emplace(node.getNode().cStr(), node);
  for (auto it = mirrors_.begin(); it != mirrors_.end();) {
    const auto found = shown.find(it->first);
    const bool same =
        found != shown.end() &&
        std::string_view(reinterpret_cast<const char*>(found->second.getDescription().begin()),
                         found->second.getDescription().size()) == it->second->description;
    if (same) {
      ++it;
      continue;
    }
    say("parameters of %s: no longer mirrored here", it->first.c_str());
    {
      // Its node's thread may wait for the robot in forward(), and the scheduler stops only
      // once it returns: answered here, as this thread would send the write.
      std::lock_guard lock(mutex_);
      for (const std::shared_ptr<Forward>& waiting : unanswered_) {
        if (waiting->node != it->first || waiting->done) continue;
        waiting->result =
            ParamSetResult{false, "node " + it->first + " stopped or changed on the robot", 0};
        waiting->done = true;
      }
    }
    wake_.notify_all();
    it = mirrors_.erase(it);
  }
  for (const auto& [node, shown_node] : shown) {
    std::map<std::string, std::string> values;
    for (const wire::ParamValue::Reader value : shown_node.getValues()) {
      values[value.getName()] = std::string(reinterpret_cast<const char*>(value.getValue().begin()),
                                            value.getValue().size());
    }
    if (const auto found = mirrors_.find(node); found != mirrors_.end()) {
      Mirror& mirror = *found->second;
      std::lock_guard lock(mutex_);
      for (auto& [name, value] : values) {
        const auto known = mirror.values.find(name);
        if (known == mirror.values.end() || known->second == value) continue;
        known->second = value;
        updates_.emplace_back(node, name, value);
      }
      wake_.notify_all();
      continue;
    }
    auto mirror = std::make_unique<Mirror>();
    const auto description_bytes = shown_node.getDescription();
    mirror->description.assign(reinterpret_cast<const char*>(description_bytes.begin()),
                               description_bytes.size());
    if (const auto failed = unmirrorable_.find(node);
        failed != unmirrorable_.end() && failed->second == mirror->description) {
      continue;  // said once; tried again when the robot shows other declarations
    }
    try {
      const TypeDescription description = TypeDescription::decode(mirror->description);
      std::vector<ParamDeclaration> declarations;
      for (ParamDeclaration& declaration : param_declarations_of(description)) {
        const auto value = values.find(declaration.name);
        if (!bridge::any_matches(node + "." + declaration.name, patterns_) ||
            value == values.end()) {
          continue;
        }
        declaration.default_value = value->second;
        mirror->values[declaration.name] = value->second;
        declarations.push_back(std::move(declaration));
      }
      if (declarations.empty()) continue;
      mirror->node = std::make_shared<MirrorNode>(
          node, std::move(declarations), sync_source_,
          [this](const std::string& owner, const std::string& name, const std::string& value) {
            return forward(owner, name, value);
          },
          // The robot's values again: a value persisted here is not the robot's.
          [this, node, shown = mirror.get()] {
            std::lock_guard lock(mutex_);
            for (const auto& [name, value] : shown->values)
              updates_.emplace_back(node, name, value);
            wake_.notify_all();
          });
      SchedulerConfig config;
      config.name("horus-remote-params-" + node)
          .handle_signals(false)
          .max_deadline_misses(std::nullopt)
          .verbose(false);
      mirror->scheduler = std::make_unique<Scheduler>(std::move(config));
      mirror->scheduler->add(mirror->node).rate(Rate::hz(1)).build();
    } catch (const std::exception& e) {
      say("cannot mirror the parameters of %s: %s", node.c_str(), e.what());
      unmirrorable_[node] = mirror->description;
      continue;
    }
    Scheduler& scheduler = *mirror->scheduler;
    const std::string name = node;
    mirror->thread = std::thread([&scheduler, name] {
      try {
        if (scheduler.run() != 0) {
          say("the parameters of %s are not mirrored here: %s", name.c_str(),
              scheduler.stop_reason().c_str());
        }
      } catch (const std::exception& e) {
        say("the parameters of %s are not mirrored here: %s", name.c_str(), e.what());
      }
    });
    say("mirroring the parameters of %s", node.c_str());
    mirrors_.emplace(node, std::move(mirror));
  }
}

void ParamMirrors::sync_loop() {
  std::unique_lock lock(mutex_);
  while (!closing_) {
    if (updates_.empty()) {
      wake_.wait(lock);
      continue;
    }
    auto [node, name, value] = std::move(updates_.front());
    updates_.pop_front();
    lock.unlock();
    try {
      // A write made here that the robot took is here already.
      if (ParamStoreReader(node, namespace_name_).get(name).value != value) {
        ParamSetOptions options;
        options.source = sync_source_;
        options.namespace_name = namespace_name_;
        options.timeout = std::chrono::seconds(2);
        const ParamSetResult result = set_param(node, name, value, options);
        if (!result.accepted) {
          say("parameter %s.%s: the robot's value is not shown here: %s", node.c_str(),
              name.c_str(), result.reason.c_str());
        }
      }
    } catch (const std::exception& e) {
      say("parameter %s.%s: the robot's value is not shown here: %s", node.c_str(), name.c_str(),
          e.what());
    }
    lock.lock();
  }
}

}  // namespace horus::remote
