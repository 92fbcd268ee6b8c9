// What both ends of a remote link share: topics opened by their recorded type, the forwarder
// that streams a local topic into a peer's Sink, the Sink that writes into a local topic, the
// TLS context made from a certificate folder, and the log.
#pragma once

#include <capnp/rpc-twoparty.h>
#include <kj/async-io.h>
#include <kj/async-unix.h>
#include <kj/compat/tls.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "horus/bridge/forwarder.hpp"
#include "horus/bridge/frame_source.hpp"
#include "horus/bridge/tls.hpp"
#include "horus/bridge/topic_watch.hpp"
#include "horus/pool_frames.hpp"
#include "horus/raw_topic.hpp"
#include "horus/topic_registry.hpp"
#include "remote.capnp.h"

namespace horus::remote {

/// The message stream of a connection, whose limit on the messages it reads (Cap'n Proto's
/// traversal limit) can be raised after it connected: TwoPartyVatNetwork keeps the ReaderOptions
/// it was made with for its whole life. Each end raises its own limit before it asks for a
/// topic or service whose messages would not fit (the robot only for what the policy lets the
/// peer write or call), so a larger message ends no connection and a small one cannot be
/// made into a flood of large ones. The network itself is given kLargestMessageWords, the
/// largest message it may send.
class LimitedMessageStream final : public capnp::MessageStream {
 public:
  /// The limit of a connection at first: topics of up to about 8 MiB need no raise (a 1080p
  /// RGB image, 6 MB, fits).
  static constexpr std::size_t kFirstLimitBytes = std::size_t{8} << 20;
  /// What a TwoPartyVatNetwork over this stream is made with: it refuses to send larger
  /// messages (a topic's messages are at most 4 GiB, the wire's UInt32, plus framing).
  static constexpr std::size_t kLargestMessageWords =
      (std::size_t{1} << 32) / sizeof(capnp::word) + 1024;

  explicit LimitedMessageStream(kj::AsyncIoStream& stream) : inner_(stream) {}

  /// Makes sure messages with `payload_bytes` of payload are read from now on.
  void make_room(std::size_t payload_bytes);
  /// Told why a read failed (a message over the limit, malformed framing, a broken stream)
  /// before the connection ends with it.
  void on_read_failure(std::function<void(const kj::Exception&)> tell) {
    on_read_failure_ = std::move(tell);
  }
  std::size_t limit_bytes() const noexcept { return limit_words_ * sizeof(capnp::word); }

  kj::Promise<kj::Maybe<capnp::MessageReaderAndFds>> tryReadMessage(
      kj::ArrayPtr<kj::AutoCloseFd> fd_space, capnp::ReaderOptions options,
      kj::ArrayPtr<capnp::word> scratch_space) override;
  kj::Promise<void> writeMessage(
      kj::ArrayPtr<const int> fds,
      kj::ArrayPtr<const kj::ArrayPtr<const capnp::word>> segments) override {
    return inner_.writeMessage(fds, segments);
  }
  kj::Promise<void> writeMessages(
      kj::ArrayPtr<kj::ArrayPtr<const kj::ArrayPtr<const capnp::word>>> messages) override {
    return inner_.writeMessages(messages);
  }
  kj::Maybe<int> getSendBufferSize() override { return inner_.getSendBufferSize(); }
  kj::Promise<void> end() override { return inner_.end(); }

  /// What a TwoPartyVatNetwork over this stream is made with.
  static capnp::ReaderOptions network_options();

 private:
  capnp::AsyncIoMessageStream inner_;
  std::size_t limit_words_ = kFirstLimitBytes / sizeof(capnp::word);
  std::function<void(const kj::Exception&)> on_read_failure_;
};

/// The event port of this process's event loop (on which Forwarders watch their topics or their
/// reader threads); set once, by the loop's maker, before any Forwarder exists.
void use_event_port(kj::UnixEventPort& port);

/// One line on stderr, "horus-remote: ...".
[[gnu::format(printf, 1, 2)]] void say(const char* format, ...);

/// Fails the current RPC call with `text` as the whole message the peer sees.
[[noreturn]] void refuse(const std::string& text);

/// The topic as its segment records it, for the wire.
void describe(const TopicInfo& info, wire::TopicInfo::Builder out);
/// The topic a TopicInfo of the wire describes (no counters).
TopicInfo topic_info(wire::TopicInfo::Reader info);
/// Why the description bytes of `info` (a peer's) are not a type description of `info`'s type
/// (one that decodes, whose root is the type, with its fingerprint), or nothing when they are or
/// are empty: a topic created with them must not mislead what reads it.
std::optional<std::string> description_problem(const TopicInfo& info);

/// What a Forwarder counts of its stream. Shared with a sink on this side that may not pass a
/// message on (a service's mirror answering a request itself), which then takes it back.
struct StreamCounts {
  std::atomic<std::uint64_t> sent{0};
  std::atomic<std::uint64_t> dropped{0};
};

/// The bytes the queues of several Forwarders (a peer's streams) may hold together.
class QueueBudget {
 public:
  explicit QueueBudget(std::size_t limit) : limit_(limit) {}
  /// Takes `bytes` of the budget, if they fit. A message larger than the whole budget fits
  /// when nothing else is queued, so that every stream can go on.
  bool take(std::size_t bytes) noexcept;
  void give_back(std::size_t bytes) noexcept { used_.fetch_sub(bytes); }

 private:
  const std::size_t limit_;
  std::atomic<std::size_t> used_{0};
};

/// How this process's Forwarders wait on their topics: in the event loop itself (an io_uring
/// futex wait of a bridge::TopicWatch, observed beside the sockets) where the kernel offers it,
/// else, or with HORUS_REMOTE_NO_IO_URING=1 in the environment, a reader thread each that hands
/// the messages to the loop. Decided once per process.
using bridge::TopicWait;
inline constexpr const char* kNoIoUring = "HORUS_REMOTE_NO_IO_URING";
TopicWait topic_wait();
/// The startup line's words for topic_wait(), and why when it is the reader thread.
std::string describe_topic_wait();

/// Streams the messages of a local topic into a peer's Sink: a reader (the event loop itself, or
/// a thread of its own: topic_wait()) takes the topic's messages as they come and queues at most
/// `queue_limit` of them (the oldest dropped beyond that: latest wins when the link is slower
/// than the publisher); the event loop sends them with Cap'n Proto's streaming flow control, so
/// a slow peer holds the queue at its bound, never more. The topic is read through a
/// bridge::FrameSource: a frame of a pool-backed type (Image, DepthImage, PointCloud, Tensor) of
/// `namespace_name` is queued as the recorder keeps it, its descriptor and the data of its block,
/// copied as it is read. Each message goes with its ticket on the topic as its sequence; every
/// message left out (dropped from the queue, overwritten in the ring before the reader read it,
/// a frame whose block was reused) is counted as dropped, and shows as a gap in the sequence.
/// With a `budget`, the queue also holds no more than the budget (shared with other Forwarders)
/// lets it: the oldest messages are dropped first, then the new one. Only the wait differs
/// between the two readers: both take frames with take_waiting() and queue them with queue().
class Forwarder final : public bridge::Forwarder {
 public:
  Forwarder(std::unique_ptr<RawTopic> topic, wire::Sink::Client sink, std::size_t queue_limit,
            std::string label, const std::string& namespace_name,
            std::shared_ptr<QueueBudget> budget = nullptr);
  /// noexcept as its base's: kj's handles it holds are declared to throw from their destructors
  /// so that kj can report a bug; none is expected here, and one would end the process.
  ~Forwarder() noexcept override;

  /// Sends until the sink fails (the peer dropped it, or the connection ended); where the event
  /// loop waits on the topic, reads it from here on as well. Called once.
  kj::Promise<void> run();
  std::uint64_t sent() const noexcept { return counts_->sent.load(); }
  std::uint64_t dropped() const noexcept { return counts_->dropped.load(); }
  const std::shared_ptr<StreamCounts>& counts() const noexcept { return counts_; }
  const std::string& label() const noexcept { return label_; }

 private:
  struct Queued {
    std::uint64_t sequence;
    std::vector<std::byte> bytes;
  };
  /// The reader thread's loop: waits on the topic (the one place that does), then takes what
  /// else is there.
  void read_loop();
  /// The event loop's reader: takes what the topic holds, then arms the watch and waits for
  /// its descriptor; again when it turns readable. Ends only by throwing (the kernel refused a
  /// wait, no memory for a frame), which ends the stream.
  kj::Promise<void> watch_topic();
  /// Queues the frames the topic holds now, without waiting, at most a ring's worth (a
  /// publisher faster than the copying does not keep the reader here); whether it took all.
  bool take_waiting();
  /// Queues `frame` for the event loop, dropping what the queue limit and the budget want.
  void queue(const bridge::Frame& frame);
  /// Counts as dropped what the source lost since this was last called; with mutex_ held when a
  /// frame is queued after those (a message taken off the queue goes with the drops before it).
  void count_lost();
  void report_drops();
  /// Drops the oldest queued message; with mutex_ held.
  void drop_oldest();
  /// Sends the queued messages, waiting for the reader when there are none.
  kj::Promise<void> send_queued();
  /// Resolves once the reader queued a message after send_queued() set waiting_.
  kj::Promise<void> reader_queued();

  bridge::FrameSource source_;
  wire::Sink::Client sink_;
  std::size_t queue_limit_;
  std::string label_;
  std::shared_ptr<QueueBudget> budget_;
  std::mutex mutex_;
  std::deque<Queued> queue_;
  /// The event loop's wait on the topic; null where a reader thread waits instead.
  std::unique_ptr<bridge::TopicWatch> watch_;
  /// The reader thread's: written when the event loop waits for its next message (`waiting_`).
  kj::AutoCloseFd wake_;
  /// Watches watch_'s descriptor (event loop reader) or wake_ (reader thread).
  kj::UnixEventPort::FdObserver observer_;
  /// The event loop reader's: fulfilled when send_queued() waits for its next message.
  kj::Own<kj::PromiseFulfiller<void>> queued_;
  bool waiting_ = false;
  std::shared_ptr<StreamCounts> counts_ = std::make_shared<StreamCounts>();
  /// The reader's: the source's count of messages it lost as counted last; what report_drops()
  /// said last, and when.
  std::uint64_t lost_ = 0;
  std::uint64_t reported_drops_ = 0;
  std::chrono::steady_clock::time_point last_report_{};
};

/// Where a horus-remote process of `namespace_name` says how its streams are doing (`horus remote
/// status` reads it): $XDG_RUNTIME_DIR/horus-remote/, else /tmp/horus-remote-UID/, one
/// NAMESPACE.PID.json per process.
std::string status_path(const std::string& namespace_name);
/// Writes the status file of this process (`role`: serve or connect): how its Forwarders wait
/// on their topics (topic_wait(): event_loop or reader_thread), every live Forwarder's and
/// StatusListing's label, messages sent and dropped. Replaced whole (a reader never sees half of
/// it).
void write_status(const std::string& path, const char* role);

/// A stream that is not a Forwarder's (the frames), in the status file while this lives.
class StatusListing {
 public:
  StatusListing(std::string label, std::shared_ptr<const StreamCounts> counts);
  ~StatusListing();
  StatusListing(const StatusListing&) = delete;
  StatusListing& operator=(const StatusListing&) = delete;

  const std::string& label() const noexcept { return label_; }
  const StreamCounts& counts() const noexcept { return *counts_; }

 private:
  std::string label_;
  std::shared_ptr<const StreamCounts> counts_;
};

/// Writes what a peer streams into a local topic: POD messages of exactly the type's size,
/// serialized ones no larger than a slot; anything else ends the stream with the reason, which
/// `refused` is told (by default, it is logged). A
/// frame of a pool-backed type (a descriptor and its data, as a Forwarder sends it) is made
/// again in a block of the "default" pool of `namespace_name`, as a replay makes it, and its
/// descriptor published.
class TopicSink final : public wire::Sink::Server {
 public:
  TopicSink(std::shared_ptr<RawTopic> topic, std::string label, const std::string& namespace_name,
            std::function<void(const std::string&)> refused = nullptr);
  ~TopicSink() noexcept(false);

  /// The largest message this sink reads: a slot's payload, or a descriptor and a block of
  /// the pool the frames are made again in.
  std::size_t largest_message() const noexcept { return largest_message_; }

 protected:
  kj::Promise<void> message(MessageContext context) override;

 private:
  std::shared_ptr<RawTopic> topic_;
  std::unique_ptr<PoolFrames> frames_;
  std::string label_;
  std::function<void(const std::string&)> refused_;
  std::size_t largest_message_;
  std::uint64_t received_ = 0;
  std::uint64_t dropped_ = 0;
};

/// A peer that connects but never finishes the TLS handshake is dropped after this.
constexpr auto kHandshakeTimeout = 10 * kj::SECONDS;

/// "HOST:PORT" of a peer's stream, or of its TLS connection's underlying one.
std::string address_of(kj::PeerIdentity& identity);

}  // namespace horus::remote
