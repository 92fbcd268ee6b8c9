// Coordinate frames across the link (`PEER read|write @frames/CHILD` rules): the robot streams
// the frames a peer may read into the peer's FrameSink and sets the ones it may write; the laptop
// sets the robot's frames in its own tree (--import-frames) and sends its own (--export-frames).
// Each side reads its tree with one TransformFeed, on a thread of its own (FrameFollower).
#pragma once

#include <kj/async.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "horus/frames.hpp"
#include "horus/transform_feed.hpp"
#include "link.hpp"
#include "remote.capnp.h"

namespace horus::remote {

/// The prefix that names a frame in policy lines: `PEER read @frames/base_link`.
inline constexpr std::string_view kFramePolicyPrefix = "@frames/";

void to_wire(const StampedTransform& transform, wire::FrameTransform::Builder out);
StampedTransform from_wire(wire::FrameTransform::Reader transform);

/// Frame names, shared between the event loop (which adds the frames it sets from the far end)
/// and a feed's thread (which leaves them out, so that no frame goes back where it came from).
class FrameNames {
 public:
  /// Whether `name` is new.
  bool add(const std::string& name);
  void remove(const std::string& name);
  bool contains(std::string_view name) const;

 private:
  mutable std::mutex mutex_;
  std::set<std::string, std::less<>> names_;
};

/// A tree's TransformFeed followed on a thread of its own (the feed sleeps until the tree
/// changes, which the event loop must never do), its batches handed to the event loop, merged
/// while the event loop is busy sending the last one. Dynamic frames whose authority is gone are
/// left out: what a dead writer left is not news, and may be what the far end itself sent before
/// a restart of either side (a frame must not go back where it came from). Static frames are
/// carried whoever set them.
class FrameFollower {
 public:
  /// `tree` must outlive the follower.
  FrameFollower(const FrameTree& tree, TransformFeed::Carried carried);
  ~FrameFollower();
  FrameFollower(const FrameFollower&) = delete;
  FrameFollower& operator=(const FrameFollower&) = delete;

  /// On the event loop: what the tree's carried frames did since the last batch taken, once
  /// there is something; the first batch (after the start or a restart) at once, even empty,
  /// so that the far end learns it has the current state.
  kj::Promise<TransformBatch> next();
  /// From the next batch on, the tree's current state again (each frame's newest transform and
  /// the whole static set), for a far end that connected (again); what was queued is dropped.
  void restart();
  /// `dropped`: dynamic transforms left out because the far end took them slower than they
  /// came; `sent` is the sender's to count.
  const std::shared_ptr<StreamCounts>& counts() const noexcept { return counts_; }

 private:
  void follow();
  /// What is queued, unless nothing is (and the first batch was taken); under mutex_.
  std::optional<TransformBatch> take_locked();

  TransformFeed feed_;
  std::mutex mutex_;
  TransformBatch queued_;
  /// The first batch is queued, empty or not.
  bool first_ready_ = false;
  kj::Own<kj::CrossThreadPromiseFulfiller<void>> waiting_;
  bool closing_ = false;
  std::atomic<bool> restart_{false};
  std::shared_ptr<StreamCounts> counts_ = std::make_shared<StreamCounts>();
  std::thread thread_;
};

/// Sets transforms from the far end in a tree, this process becoming their authority: a
/// dynamic stamp not newer than the child's newest set here is skipped (a reconnected far end
/// sends its newest again), and a static transform set already the same is not set again.
class FrameSetter {
 public:
  explicit FrameSetter(FrameTree& tree) : tree_(tree) {}
  /// Why the tree refused the transform; empty when it was set or skipped.
  std::string set(const StampedTransform& transform, bool is_static);

 private:
  std::chrono::nanoseconds newest_in_tree(std::string_view child) const;

  struct Static {
    std::string parent;
    Transform transform;
  };
  FrameTree& tree_;
  std::map<std::string, std::chrono::nanoseconds> newest_;
  std::map<std::string, Static> statics_;
};

/// The robot's frames as every connection of `horus remote serve` shares them: the namespace's
/// tree, opened at the first peer that asks for frames.
class ServedFrames {
 public:
  explicit ServedFrames(std::string namespace_name) : namespace_name_(std::move(namespace_name)) {}
  FrameTree& tree();
  FrameSetter& setter();

 private:
  std::string namespace_name_;
  std::unique_ptr<FrameTree> tree_;
  std::unique_ptr<FrameSetter> setter_;
};

/// The robot's side of Session.frames: streams what `follower` gives into the peer's sink.
class FrameStream final : public wire::Subscription::Server {
 public:
  FrameStream(std::unique_ptr<FrameFollower> follower, wire::FrameSink::Client sink,
              std::string label);

 protected:
  kj::Promise<void> stats(StatsContext context) override;

 private:
  kj::Promise<void> send_next();

  std::unique_ptr<FrameFollower> follower_;
  wire::FrameSink::Client sink_;
  StatusListing listing_;
  /// Declared last: cancelled before the follower it waits on is destroyed.
  kj::Promise<void> task_;
};

/// What outlives a connection on the laptop: its tree, the robot's frames set here (never sent
/// back), and the feed of the frames it exports.
class LaptopFrames {
 public:
  LaptopFrames(const std::string& namespace_name, std::vector<std::string> imports,
               std::vector<std::string> exports);

  /// Frames the link sets here, and what the link sends to the robot: one connection's.
  /// `session`'s connection is new: the robot is given the exported frames' current state.
  kj::Promise<void> run(wire::Session::Client session);

 private:
  class Importer;
  /// Whether the robot's `child` may be set here: not when a live local process sets it (a
  /// frame this side exports comes back no more than one of the robot's takes its place).
  bool importable(const std::string& child);
  kj::Promise<void> export_next(wire::Session::Client session,
                                std::shared_ptr<std::set<std::string>> refused);

  std::vector<std::string> imports_;
  std::vector<std::string> exports_;
  FrameTree tree_;
  FrameSetter setter_{tree_};
  std::shared_ptr<FrameNames> imported_ = std::make_shared<FrameNames>();
  /// Frames said once not to be importable here, and the robot's refusals said once.
  std::set<std::string> told_;
  /// importable(), by frame, for the connection's life.
  std::map<std::string, bool> importable_;
  std::unique_ptr<FrameFollower> exported_;
  std::unique_ptr<StatusListing> listing_;
};

}  // namespace horus::remote
