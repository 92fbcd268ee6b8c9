// What both ends of a remote link share: topics opened by their recorded type, the forwarder
// that streams a local topic into a peer's Sink, the Sink that writes into a local topic, the
// TLS context made from a certificate folder, and the log.
#pragma once

#include <capnp/rpc-twoparty.h>
#include <kj/async-io.h>
#include <kj/async-unix.h>
#include <kj/compat/tls.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

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

/// The event port of this process's event loop (which Forwarders watch their reader threads
/// on); set once, by the loop's maker, before any Forwarder exists.
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
/// Opens (or creates) `info.name` in `namespace_name` with the type and sizes of `info`; throws
/// horus::Error naming both types when the topic exists with another.
std::unique_ptr<RawTopic> open_topic(const TopicInfo& info, const std::string& namespace_name);

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

/// Streams the messages of a local topic into a peer's Sink: a thread waits on the topic and
/// queues at most `queue_limit` messages (the oldest dropped beyond that: latest wins when the
/// link is slower than the publisher); the event loop sends them with Cap'n Proto's streaming
/// flow control, so a slow peer holds the queue at its bound, never more. A frame of a
/// pool-backed type (Image, DepthImage, PointCloud, Tensor) of `namespace_name` is queued as
/// the recorder keeps it: its descriptor and the data of its block, copied as it is read. Each
/// message goes with its ticket on the topic as its sequence; every message left out (dropped
/// from the queue, overwritten in the ring before the thread read it, a frame whose block was
/// reused) is counted as dropped, and shows as a gap in the sequence. With a `budget`, the queue
/// also holds no more than the budget (shared with other Forwarders) lets it: the oldest
/// messages are dropped first, then the new one.
class Forwarder {
 public:
  Forwarder(std::unique_ptr<RawTopic> topic, wire::Sink::Client sink, std::size_t queue_limit,
            std::string label, const std::string& namespace_name,
            std::shared_ptr<QueueBudget> budget = nullptr);
  Forwarder(const Forwarder&) = delete;
  Forwarder& operator=(const Forwarder&) = delete;
  ~Forwarder();

  /// Sends until the sink fails (the peer dropped it, or the connection ended).
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
  void read_loop();
  void report_drops();
  /// Drops the oldest queued message; with mutex_ held.
  void drop_oldest();

  std::unique_ptr<RawTopic> topic_;
  /// Set for a pool-backed type.
  std::unique_ptr<PoolFrames> frames_;
  wire::Sink::Client sink_;
  std::size_t queue_limit_;
  std::string label_;
  std::shared_ptr<QueueBudget> budget_;
  std::mutex mutex_;
  std::deque<Queued> queue_;
  /// Written by the reader thread when the event loop waits for its next message (`waiting_`),
  /// and watched by the loop.
  kj::AutoCloseFd wake_;
  kj::UnixEventPort::FdObserver wake_observer_;
  bool waiting_ = false;
  std::atomic<bool> stopping_{false};
  std::shared_ptr<StreamCounts> counts_ = std::make_shared<StreamCounts>();
  /// The reader thread's: the topic's count of messages it lost as read last; what
  /// report_drops() said last, and when.
  std::uint64_t lost_ = 0;
  std::uint64_t reported_drops_ = 0;
  std::chrono::steady_clock::time_point last_report_{};
  /// Last: started once everything it reads is there.
  std::thread reader_;
};

/// Where a horus-remote process of `namespace_name` says how its streams are doing (`horus remote
/// status` reads it): $XDG_RUNTIME_DIR/horus-remote/, else /tmp/horus-remote-UID/, one
/// NAMESPACE.PID.json per process.
std::string status_path(const std::string& namespace_name);
/// Writes the status file of this process (`role`: serve or connect): every live Forwarder's
/// label, messages sent and dropped. Replaced whole (a reader never sees half of it).
void write_status(const std::string& path, const char* role);

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

/// The certificate folder of `horus remote keygen`: DIR/ca.crt and DIR/NAME.{crt,key}.
struct Credentials {
  kj::TlsCertificate authority;
  kj::TlsKeypair own;
};
/// Throws std::runtime_error naming the missing or unreadable file.
Credentials load_credentials(const std::string& folder, const std::string& name);
/// Mutual TLS trusting only the folder's CA: a peer must present a certificate it signed.
kj::Own<kj::TlsContext> tls_context(const Credentials& credentials, kj::Timer& timer);

/// "HOST:PORT" of a peer's stream, or of its TLS connection's underlying one.
std::string address_of(kj::PeerIdentity& identity);

}  // namespace horus::remote
