// Coordinate frames across the link: the feeds' threads, the setting of the far end's frames,
// the robot's stream and the laptop's import and export (remote_frames.hpp).
#include "remote_frames.hpp"

#include <unistd.h>

#include <algorithm>
#include <utility>

#include "horus/bridge/topic_policy.hpp"
#include "link.hpp"

namespace horus::remote {

namespace {

/// How long a feed's thread sleeps at most before it looks whether it should end.
constexpr auto kFeedWait = std::chrono::milliseconds(100);
/// How often a feed looks again whether a frame left by a dead writer has a new one.
/// Dynamic transforms queued for a far end that takes them slower than they come, at most: a
/// second of 80 frames at 100 Hz. Beyond it the oldest are dropped (latest wins).
constexpr std::size_t kMostQueuedTransforms = 8192;

void fill(const std::vector<StampedTransform>& transforms,
          capnp::List<wire::FrameTransform>::Builder out) {
  for (unsigned i = 0; i < transforms.size(); ++i) to_wire(transforms[i], out[i]);
}

FrameTreeOptions tree_options(const std::string& namespace_name) {
  FrameTreeOptions options;
  options.namespace_name = namespace_name;
  return options;
}

bool same(const Transform& a, const Transform& b) {
  return a.translation.x == b.translation.x && a.translation.y == b.translation.y &&
         a.translation.z == b.translation.z && a.rotation.x == b.rotation.x &&
         a.rotation.y == b.rotation.y && a.rotation.z == b.rotation.z &&
         a.rotation.w == b.rotation.w;
}

}  // namespace

void to_wire(const StampedTransform& transform, wire::FrameTransform::Builder out) {
  out.setParent(transform.parent);
  out.setChild(transform.child);
  out.setStamp(transform.stamp.count());
  auto translation = out.initTranslation();
  translation.setX(transform.transform.translation.x);
  translation.setY(transform.transform.translation.y);
  translation.setZ(transform.transform.translation.z);
  auto rotation = out.initRotation();
  rotation.setX(transform.transform.rotation.x);
  rotation.setY(transform.transform.rotation.y);
  rotation.setZ(transform.transform.rotation.z);
  rotation.setW(transform.transform.rotation.w);
}

StampedTransform from_wire(wire::FrameTransform::Reader transform) {
  StampedTransform out;
  out.parent = transform.getParent().cStr();
  out.child = transform.getChild().cStr();
  out.stamp = std::chrono::nanoseconds(transform.getStamp());
  const auto translation = transform.getTranslation();
  out.transform.translation = {translation.getX(), translation.getY(), translation.getZ()};
  const auto rotation = transform.getRotation();
  out.transform.rotation = {rotation.getX(), rotation.getY(), rotation.getZ(), rotation.getW()};
  return out;
}

bool FrameNames::add(const std::string& name) {
  std::lock_guard lock(mutex_);
  return names_.insert(name).second;
}

void FrameNames::remove(const std::string& name) {
  std::lock_guard lock(mutex_);
  names_.erase(name);
}

bool FrameNames::contains(std::string_view name) const {
  std::lock_guard lock(mutex_);
  return names_.find(name) != names_.end();
}

FrameFollower::FrameFollower(const FrameTree& tree, TransformFeed::Carried carried)
    : feed_(tree, std::move(carried), {.skip_dead_authorities = true}),
      thread_([this] { follow(); }) {}

FrameFollower::~FrameFollower() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  thread_.join();
}

void FrameFollower::restart() {
  std::lock_guard lock(mutex_);
  queued_ = {};
  first_ready_ = false;
  restart_ = true;
}

void FrameFollower::follow() {
  bool first = true;
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (closing_) return;
    }
    if (restart_.exchange(false)) {
      feed_.restart();
      first = true;
    }
    TransformBatch batch = feed_.next(kFeedWait);
    if (batch.empty() && !first) continue;
    std::lock_guard lock(mutex_);
    // A restart asked while this batch was read makes the next one whole: this one is stale.
    if (restart_) continue;
    first_ready_ = first_ready_ || first;
    first = false;
    for (StampedTransform& transform : batch.dynamic) {
      queued_.dynamic.push_back(std::move(transform));
    }
    if (queued_.dynamic.size() > kMostQueuedTransforms) {
      const std::size_t excess = queued_.dynamic.size() - kMostQueuedTransforms;
      queued_.dynamic.erase(queued_.dynamic.begin(),
                            queued_.dynamic.begin() + static_cast<std::ptrdiff_t>(excess));
      counts_->dropped += excess;
    }
    if (batch.statics) queued_.statics = std::move(batch.statics);
    if (waiting_) {
      waiting_->fulfill();
      waiting_ = nullptr;
    }
  }
}

std::optional<TransformBatch> FrameFollower::take_locked() {
  if (queued_.empty() && !first_ready_) return std::nullopt;
  first_ready_ = false;
  return std::exchange(queued_, TransformBatch{});
}

kj::Promise<TransformBatch> FrameFollower::next() {
  auto waiting = kj::newPromiseAndCrossThreadFulfiller<void>();
  {
    std::lock_guard lock(mutex_);
    if (std::optional<TransformBatch> batch = take_locked()) return kj::mv(*batch);
    waiting_ = kj::mv(waiting.fulfiller);
  }
  return waiting.promise.then([this] {
    std::optional<TransformBatch> batch;
    {
      std::lock_guard lock(mutex_);
      batch = take_locked();
    }
    // Queued, then dropped by a restart before this ran: wait for the next.
    if (!batch) return next();
    return kj::Promise<TransformBatch>(kj::mv(*batch));
  });
}

std::chrono::nanoseconds FrameSetter::newest_in_tree(std::string_view child) const {
  for (const FrameInfo& info : tree_.frames(false)) {
    if (info.name == child && !info.is_static && info.updates > 0) return info.latest;
  }
  return std::chrono::nanoseconds::min();
}

std::string FrameSetter::set(const StampedTransform& transform, bool is_static) {
  try {
    if (is_static) {
      const auto known = statics_.find(transform.child);
      if (known != statics_.end() && known->second.parent == transform.parent &&
          same(known->second.transform, transform.transform)) {
        return {};
      }
      tree_.set_static_transform(transform.parent, transform.child, transform.transform);
      statics_[transform.child] = Static{transform.parent, transform.transform};
      newest_.erase(transform.child);
      return {};
    }
    const auto newest = newest_.find(transform.child);
    // What the tree holds already (this frame's writer before a restart of this process, or of
    // the far end's) is not written again.
    if (transform.stamp <=
        (newest != newest_.end() ? newest->second : newest_in_tree(transform.child))) {
      return {};
    }
    tree_.set_transform(transform.parent, transform.child, transform.transform, transform.stamp);
    newest_[transform.child] = transform.stamp;
    statics_.erase(transform.child);
    return {};
  } catch (const FrameError& e) {
    return e.what();
  }
}

FrameTree& ServedFrames::tree() {
  if (!tree_) tree_ = std::make_unique<FrameTree>(tree_options(namespace_name_));
  return *tree_;
}

FrameSetter& ServedFrames::setter() {
  if (!setter_) setter_ = std::make_unique<FrameSetter>(tree());
  return *setter_;
}

FrameStream::FrameStream(std::unique_ptr<FrameFollower> follower, wire::FrameSink::Client sink,
                         std::string label)
    : follower_(std::move(follower)),
      sink_(kj::mv(sink)),
      listing_(label, follower_->counts()),
      task_(send_next().eagerlyEvaluate([label](kj::Exception&& e) {
        say("%s ended: %s", label.c_str(), e.getDescription().cStr());
      })) {}

kj::Promise<void> FrameStream::stats(StatsContext context) {
  context.getResults().setSent(follower_->counts()->sent.load());
  context.getResults().setDropped(follower_->counts()->dropped.load());
  return kj::READY_NOW;
}

kj::Promise<void> FrameStream::send_next() {
  return follower_->next().then([this](TransformBatch&& batch) {
    auto request = sink_.transformsRequest();
    fill(batch.dynamic, request.initDynamic(static_cast<unsigned>(batch.dynamic.size())));
    if (batch.statics) {
      request.setStaticsChanged(true);
      fill(*batch.statics, request.initStatics(static_cast<unsigned>(batch.statics->size())));
    }
    follower_->counts()->sent += batch.dynamic.size() + (batch.statics ? batch.statics->size() : 0);
    return request.send().then([this] { return send_next(); });
  });
}

/// The laptop's FrameSink: the robot's frames set in the laptop's tree.
class LaptopFrames::Importer final : public wire::FrameSink::Server {
 public:
  Importer(LaptopFrames& frames, kj::Own<kj::PromiseFulfiller<void>> caught_up)
      : frames_(frames), caught_up_(kj::mv(caught_up)) {}

 protected:
  kj::Promise<void> transforms(TransformsContext context) override {
    KJ_DEFER(if (caught_up_->isWaiting()) caught_up_->fulfill());
    const auto params = context.getParams();
    for (const wire::FrameTransform::Reader transform : params.getDynamic()) {
      import(from_wire(transform), false);
    }
    if (params.getStaticsChanged()) {
      for (const wire::FrameTransform::Reader transform : params.getStatics()) {
        import(from_wire(transform), true);
      }
    }
    return kj::READY_NOW;
  }

 private:
  void import(const StampedTransform& transform, bool is_static) {
    // Both ends check: the robot sends what the patterns name.
    if (!bridge::any_matches(transform.child, frames_.imports_) ||
        !frames_.importable(transform.child)) {
      return;
    }
    frames_.imported_->add(transform.child);
    const std::string refused = frames_.setter_.set(transform, is_static);
    if (!refused.empty() && frames_.told_.insert("import " + transform.child).second) {
      say("cannot import frame %s: %s", transform.child.c_str(), refused.c_str());
    } else if (refused.empty() && frames_.told_.insert("imported " + transform.child).second) {
      say("importing frame %s", transform.child.c_str());
    }
  }

  LaptopFrames& frames_;
  /// Fulfilled by the robot's first batch, which has what it sends of the current state.
  kj::Own<kj::PromiseFulfiller<void>> caught_up_;
};

LaptopFrames::LaptopFrames(const std::string& namespace_name, std::vector<std::string> imports,
                           std::vector<std::string> exports)
    : imports_(std::move(imports)),
      exports_(std::move(exports)),
      tree_(tree_options(namespace_name)) {
  if (exports_.empty()) return;
  exported_ = std::make_unique<FrameFollower>(tree_, [this](std::string_view child) {
    return bridge::any_matches(child, exports_) && !imported_->contains(child);
  });
  listing_ = std::make_unique<StatusListing>("frames to the robot", exported_->counts());
}

bool LaptopFrames::importable(const std::string& child) {
  if (const auto known = importable_.find(child); known != importable_.end()) {
    return known->second;
  }
  // One look at the tree (and /proc) for every frame it holds, as the robot's first batch
  // names them all at once.
  const auto self = static_cast<std::uint32_t>(::getpid());
  for (const FrameInfo& info : tree_.frames()) {
    const bool free =
        info.authority_pid == 0 || info.authority_pid == self || !info.authority_alive;
    importable_.emplace(info.name, free);
    if (!free && info.name == child && !bridge::any_matches(child, exports_) &&
        told_.insert("import " + child).second) {
      say("not importing frame %s: pid %u (%s) sets it here", child.c_str(), info.authority_pid,
          info.authority_program.c_str());
    }
  }
  return importable_.emplace(child, true).first->second;
}

kj::Promise<void> LaptopFrames::run(wire::Session::Client session) {
  importable_.clear();
  kj::Promise<void> importing = kj::NEVER_DONE;
  // The export waits for the robot's first batch: the frames the robot's set here again
  // (this process's earlier ones, or a connect process's before it) are not exported back.
  kj::Promise<void> caught_up = kj::READY_NOW;
  if (!imports_.empty()) {
    auto first = kj::newPromiseAndFulfiller<void>();
    caught_up = kj::mv(first.promise);
    auto request = session.framesRequest();
    auto patterns = request.initPatterns(static_cast<unsigned>(imports_.size()));
    for (unsigned i = 0; i < imports_.size(); ++i) patterns.set(i, imports_[i]);
    request.setSink(kj::heap<Importer>(*this, kj::mv(first.fulfiller)));
    importing = request.send().then(
        [](capnp::Response<wire::Session::FramesResults>&& response) -> kj::Promise<void> {
          // Held while the connection lasts: the robot streams as long as it is.
          return kj::Promise<void>(kj::NEVER_DONE).attach(response.getSubscription());
        });
  }
  if (!exported_) return importing;
  return importing.exclusiveJoin(caught_up.then([this, session = kj::mv(session)]() mutable {
    exported_->restart();
    return export_next(kj::mv(session), std::make_shared<std::set<std::string>>());
  }));
}

kj::Promise<void> LaptopFrames::export_next(wire::Session::Client session,
                                            std::shared_ptr<std::set<std::string>> refused) {
  return exported_->next().then([this, session,
                                 refused](TransformBatch&& batch) mutable -> kj::Promise<void> {
    if (batch.empty()) return export_next(session, refused);
    auto request = session.setFramesRequest();
    // What the robot refused on this connection is not sent again on it.
    std::erase_if(batch.dynamic,
                  [&](const StampedTransform& t) { return refused->count(t.child) != 0; });
    fill(batch.dynamic, request.initDynamic(static_cast<unsigned>(batch.dynamic.size())));
    if (batch.statics) {
      std::erase_if(*batch.statics,
                    [&](const StampedTransform& t) { return refused->count(t.child) != 0; });
      fill(*batch.statics, request.initStatics(static_cast<unsigned>(batch.statics->size())));
    }
    exported_->counts()->sent += batch.dynamic.size() + (batch.statics ? batch.statics->size() : 0);
    std::set<std::string> sent;
    for (const StampedTransform& t : batch.dynamic) sent.insert(t.child);
    if (batch.statics) {
      for (const StampedTransform& t : *batch.statics) sent.insert(t.child);
    }
    return request.send().then(
        [this, session, refused, sent = std::move(sent)](
            capnp::Response<wire::Session::SetFramesResults>&& response) mutable {
          for (const wire::FrameRefusal::Reader refusal : response.getRefusals()) {
            const std::string child = refusal.getChild();
            refused->insert(child);
            if (told_.insert("refused " + child).second) {
              say("the robot refused frame %s: %s", child.c_str(), refusal.getReason().cStr());
            }
          }
          for (const std::string& child : sent) {
            if (refused->count(child) == 0 && told_.insert("exported " + child).second) {
              say("exporting frame %s", child.c_str());
            }
          }
          return export_next(session, refused);
        });
  });
}

}  // namespace horus::remote
