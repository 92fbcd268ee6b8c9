#include "link.hpp"

#include "horus/bridge/identity.hpp"
#include "horus/error.hpp"
#include "horus/json_string.hpp"
#include "horus/tensor_pool.hpp"
#include "horus/type_description.hpp"

#include <sys/eventfd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace horus::remote {

namespace {

/// At most one drop report per stream in this interval.
constexpr auto kDropReportInterval = std::chrono::seconds(5);

/// The event loop's (use_event_port).
kj::UnixEventPort* event_port = nullptr;

kj::AutoCloseFd new_eventfd() {
  const int fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (fd < 0)
    throw std::runtime_error(std::string("cannot make an eventfd: ") + std::strerror(errno));
  return kj::AutoCloseFd(fd);
}

/// The live forwarders and other streams of this process, for its status file.
std::mutex forwarders_mutex;
std::vector<const Forwarder*> forwarders;
std::vector<const StatusListing*> listings;

/// What a queued message costs beyond its bytes (its entry, its allocation), charged to a
/// QueueBudget with them.
constexpr std::size_t kQueuedRecordBytes = 64;

/// Room for the message framing around the largest payload.
constexpr std::size_t kFramingBytes = 4096;

/// The frames of a topic's type, when it is pool-backed. `keep`: how many frames made again
/// hold their blocks (as many as the topic's ring gives out).
std::unique_ptr<PoolFrames> pool_frames(const RawTopic& topic, const std::string& namespace_name,
                                        std::size_t keep) {
  return make_pool_frames(topic.type().name, topic.type().fingerprint, namespace_name, keep);
}

}  // namespace

void LimitedMessageStream::make_room(std::size_t payload_bytes) {
  limit_words_ = std::max(limit_words_, (payload_bytes + kFramingBytes) / sizeof(capnp::word) + 1);
}

kj::Promise<kj::Maybe<capnp::MessageReaderAndFds>> LimitedMessageStream::tryReadMessage(
    kj::ArrayPtr<kj::AutoCloseFd> fd_space, capnp::ReaderOptions options,
    kj::ArrayPtr<capnp::word> scratch_space) {
  options.traversalLimitInWords = limit_words_;
  auto read = inner_.tryReadMessage(fd_space, options, scratch_space);
  if (!on_read_failure_) return read;
  return read.catch_(
      [this](kj::Exception&& e) -> kj::Promise<kj::Maybe<capnp::MessageReaderAndFds>> {
        on_read_failure_(e);
        return kj::mv(e);
      });
}

bool QueueBudget::take(std::size_t bytes) noexcept {
  const std::size_t before = used_.fetch_add(bytes);
  if (before == 0 || before + bytes <= limit_) return true;
  used_.fetch_sub(bytes);
  return false;
}

capnp::ReaderOptions LimitedMessageStream::network_options() {
  capnp::ReaderOptions options;
  options.traversalLimitInWords = kLargestMessageWords;
  return options;
}

void use_event_port(kj::UnixEventPort& port) { event_port = &port; }

void say(const char* format, ...) {
  std::va_list arguments;
  va_start(arguments, format);
  std::string line = "horus-remote: ";
  char text[1024];
  std::vsnprintf(text, sizeof text, format, arguments);
  va_end(arguments);
  line += text;
  line += '\n';
  std::fputs(line.c_str(), stderr);
}

void refuse(const std::string& text) {
  kj::throwFatalException(
      kj::Exception(kj::Exception::Type::FAILED, __FILE__, __LINE__, kj::heapString(text)));
}

void describe(const TopicInfo& info, wire::TopicInfo::Builder out) {
  out.setName(info.name);
  out.setType(info.type_name);
  out.setFingerprint(info.fingerprint);
  out.setSchema(info.schema);
  out.setIsPod(info.is_pod);
  out.setMaxMessageSize(static_cast<std::uint32_t>(info.max_message_size));
  out.setCapacity(static_cast<std::uint32_t>(info.capacity));
  out.setDescription(kj::arrayPtr(reinterpret_cast<const capnp::byte*>(info.description.data()),
                                  info.description.size()));
}

TopicInfo topic_info(wire::TopicInfo::Reader info) {
  TopicInfo out;
  out.name = info.getName();
  out.type_name = info.getType();
  out.fingerprint = info.getFingerprint();
  out.schema = info.getSchema();
  out.is_pod = info.getIsPod();
  out.max_message_size = info.getMaxMessageSize();
  out.capacity = info.getCapacity();
  const capnp::Data::Reader description = info.getDescription();
  out.description.assign(reinterpret_cast<const char*>(description.begin()), description.size());
  return out;
}

std::optional<std::string> description_problem(const TopicInfo& info) {
  if (info.description.empty()) return std::nullopt;
  try {
    const TypeDescription description = TypeDescription::decode(info.description);
    const MessageType& root = description.root_message();
    if (description.root == info.type_name && root.fingerprint == info.fingerprint) {
      return std::nullopt;
    }
    return "its type description is of " + description.root + " (fingerprint " +
           bridge::fingerprint_hex(root.fingerprint) + "), not of " + info.type_name +
           " (fingerprint " + bridge::fingerprint_hex(info.fingerprint) + ")";
  } catch (const TypeDescriptionError& e) {
    return std::string("its type description is not one: ") + e.what();
  }
}

TopicWait topic_wait() {
  static const TopicWait wait = bridge::choose_topic_wait(kNoIoUring);
  return wait;
}

std::string describe_topic_wait() {
  if (topic_wait() == TopicWait::EventLoop) {
    return "local topics are waited on in the event loop (io_uring futex waits)";
  }
  return "local topics are waited on by a reader thread each (" +
         bridge::reader_threads_reason(kNoIoUring) + ")";
}

namespace {

/// The event loop's watch on `topic`, or null where a reader thread waits instead (said once per
/// topic when the kernel refuses a ring of its own).
std::unique_ptr<bridge::TopicWatch> watch_if_offered(RawTopic& topic, const std::string& label) {
  if (topic_wait() != TopicWait::EventLoop) return nullptr;
  try {
    return std::make_unique<bridge::TopicWatch>(topic);
  } catch (const Error& e) {
    say("%s: %s; a reader thread waits on it instead", label.c_str(), e.what());
    return nullptr;
  }
}

}  // namespace

Forwarder::Forwarder(std::unique_ptr<RawTopic> topic, wire::Sink::Client sink,
                     std::size_t queue_limit, std::string label, const std::string& namespace_name,
                     std::shared_ptr<QueueBudget> budget)
    : bridge::Forwarder("horus-remote: " + label, nullptr),
      source_(std::move(topic), namespace_name),
      sink_(std::move(sink)),
      queue_limit_(queue_limit),
      label_(std::move(label)),
      budget_(std::move(budget)),
      watch_(watch_if_offered(source_.topic(), label_)),
      wake_(watch_ ? kj::AutoCloseFd() : new_eventfd()),
      observer_(*event_port, watch_ ? watch_->fd() : wake_.get(),
                kj::UnixEventPort::FdObserver::OBSERVE_READ) {
  if (!watch_) start([this] { read_loop(); });
  std::lock_guard lock(forwarders_mutex);
  forwarders.push_back(this);
}

Forwarder::~Forwarder() noexcept {
  {
    std::lock_guard lock(forwarders_mutex);
    forwarders.erase(std::find(forwarders.begin(), forwarders.end(), this));
  }
  stop();
  if (budget_) {
    for (const Queued& message : queue_) {
      budget_->give_back(message.bytes.size() + kQueuedRecordBytes);
    }
  }
  if (dropped() != 0) {
    say("ended after " + std::to_string(sent()) + " messages sent, " + std::to_string(dropped()) +
        " dropped");
  }
}

void Forwarder::read_loop() {
  while (!stopping()) {
    // The one wait on the topic of a reader thread (the event loop's is watch_topic()'s).
    const std::optional<bridge::Frame> frame = source_.next(kPoll);
    if (!frame) {
      count_lost();  // frames skipped for their reused blocks, counted as met
      continue;
    }
    queue(*frame);
    take_waiting();
  }
}

kj::Promise<void> Forwarder::watch_topic() {
  watch_->complete();
  bool took_all = take_waiting();
  // arm() refuses while a message is there: one came since take_waiting() looked.
  while (took_all && !watch_->arm()) took_all = take_waiting();
  if (!took_all) {
    // Lets the sends go first; the topic is read again right after.
    return kj::evalLater([this] { return watch_topic(); });
  }
  return observer_.whenBecomesReadable().then([this] { return watch_topic(); });
}

bool Forwarder::take_waiting() {
  for (std::size_t taken = 0; taken < source_.topic().capacity(); ++taken) {
    if (stopping()) return true;
    const std::optional<bridge::Frame> frame = source_.try_next();
    if (!frame) {
      count_lost();
      return true;
    }
    queue(*frame);
  }
  return false;
}

void Forwarder::count_lost() {
  // What the ring overwrote before the reader took it, and frames whose block was freed or
  // reused since (a local subscriber would refuse them too), are left out of the stream.
  const std::uint64_t lost = source_.lost() - lost_;
  lost_ += lost;
  counts_->dropped.fetch_add(lost);
}

void Forwarder::queue(const bridge::Frame& frame) {
  std::vector<std::byte> message(frame.bytes.begin(), frame.bytes.end());
  {
    // Counted with the queue locked: a message taken off it goes with the drops of those older.
    std::lock_guard lock(mutex_);
    count_lost();
    if (queue_.size() >= queue_limit_) drop_oldest();
    const std::size_t cost = message.size() + kQueuedRecordBytes;
    bool fits = !budget_ || budget_->take(cost);
    while (!fits && !queue_.empty()) {
      drop_oldest();
      fits = budget_->take(cost);
    }
    if (!fits) {  // the peer's other streams hold its budget
      counts_->dropped.fetch_add(1);
      return;
    }
    queue_.push_back(Queued{frame.sequence, std::move(message)});
    if (waiting_) {
      waiting_ = false;
      if (watch_) {
        queued_->fulfill();
      } else {
        const std::uint64_t one = 1;
        static_cast<void>(::write(wake_, &one, sizeof one));
      }
    }
  }
  // Here, not where messages are sent: a peer that stopped reading stops the sending too.
  report_drops();
}

void Forwarder::drop_oldest() {
  if (budget_) budget_->give_back(queue_.front().bytes.size() + kQueuedRecordBytes);
  queue_.pop_front();
  counts_->dropped.fetch_add(1);
}

void Forwarder::report_drops() {
  const std::uint64_t dropped = this->dropped();
  const auto now = std::chrono::steady_clock::now();
  if (dropped == reported_drops_ || now - last_report_ < kDropReportInterval) {
    return;
  }
  say(std::to_string(dropped) +
      " messages dropped so far (the link is slower than the publisher; latest wins)");
  reported_drops_ = dropped;
  last_report_ = now;
}

kj::Promise<void> Forwarder::run() {
  if (!watch_) return send_queued();
  // evalNow: a first read that throws ends the stream as a later one would.
  return send_queued().exclusiveJoin(kj::evalNow([this] { return watch_topic(); }));
}

kj::Promise<void> Forwarder::reader_queued() {
  if (watch_) {
    auto queued = kj::newPromiseAndFulfiller<void>();
    queued_ = kj::mv(queued.fulfiller);
    return kj::mv(queued.promise);
  }
  // Woken through an eventfd the loop watches, not a kj cross-thread fulfiller (a promise
  // made, locked and queued per message): bench/remote/RESULTS.md, "Experiments".
  return observer_.whenBecomesReadable().then([this] {
    std::uint64_t count = 0;
    static_cast<void>(::read(wake_, &count, sizeof count));
  });
}

kj::Promise<void> Forwarder::send_queued() {
  std::unique_lock lock(mutex_);
  if (queue_.empty()) {
    waiting_ = true;
    lock.unlock();
    return reader_queued().then([this] { return send_queued(); });
  }
  const Queued message = std::move(queue_.front());
  queue_.pop_front();
  if (budget_) budget_->give_back(message.bytes.size() + kQueuedRecordBytes);
  const std::uint64_t dropped_so_far = dropped();
  lock.unlock();
  auto request = sink_.messageRequest();
  request.setSequence(message.sequence);
  request.setDropped(dropped_so_far);
  request.setData(kj::arrayPtr(reinterpret_cast<const capnp::byte*>(message.bytes.data()),
                               message.bytes.size()));
  counts_->sent.fetch_add(1);
  return request.send().then([this] { return send_queued(); });
}

TopicSink::TopicSink(std::shared_ptr<RawTopic> topic, std::string label,
                     const std::string& namespace_name,
                     std::function<void(const std::string&)> refused)
    : topic_(std::move(topic)),
      frames_(pool_frames(*topic_, namespace_name, topic_->capacity())),
      label_(std::move(label)),
      refused_(std::move(refused)),
      largest_message_(topic_->payload_capacity()) {
  if (frames_) {
    TensorPoolOptions options;
    options.namespace_name = namespace_name;
    largest_message_ += TensorPool::open("default", options).block_size();
  }
}

TopicSink::~TopicSink() noexcept(false) {
  if (dropped_ != 0) {
    say("%s: ended after %llu messages received, %llu dropped by the sender", label_.c_str(),
        static_cast<unsigned long long>(received_), static_cast<unsigned long long>(dropped_));
  }
}

kj::Promise<void> TopicSink::message(MessageContext context) {
  const auto params = context.getParams();
  const capnp::Data::Reader data = params.getData();
  const TypeIdentity& type = topic_->type();
  std::span<const std::byte> message(reinterpret_cast<const std::byte*>(data.begin()), data.size());
  std::string wrong;
  if (frames_) {
    try {
      message = frames_->replay(std::span(data.begin(), data.size()));
      if (message.empty()) wrong = "a malformed frame of " + type.name;
    } catch (const Error& e) {  // the pool has no free block: this frame is lost, as on a drop
      say("%s: %s", label_.c_str(), e.what());
      return kj::READY_NOW;
    }
  } else if (type.is_pod && data.size() != type.size) {
    wrong = "a " + type.name + " is " + std::to_string(type.size) + " bytes, not " +
            std::to_string(data.size());
  } else if (data.size() > topic_->payload_capacity()) {
    wrong = "a message of " + std::to_string(data.size()) + " bytes is over the topic's limit of " +
            std::to_string(topic_->payload_capacity());
  }
  if (!wrong.empty()) {
    if (refused_) {
      refused_(wrong);
    } else {
      say("%s: %s; the stream ends", label_.c_str(), wrong.c_str());
    }
    refuse(label_ + ": " + wrong);
  }
  topic_->send(message);
  ++received_;
  dropped_ = params.getDropped();
  return kj::READY_NOW;
}

std::string status_path(const std::string& namespace_name) {
  const char* runtime = std::getenv("XDG_RUNTIME_DIR");
  const std::string folder = runtime != nullptr && *runtime != '\0'
                                 ? std::string(runtime) + "/horus-remote"
                                 : "/tmp/horus-remote-" + std::to_string(::getuid());
  ::mkdir(folder.c_str(), 0700);
  return folder + "/" + namespace_name + "." + std::to_string(::getpid()) + ".json";
}

void write_status(const std::string& path, const char* role) {
  std::string text = "{\"pid\": " + std::to_string(::getpid()) + ", \"role\": \"" + role +
                     "\", \"topic_wait\": \"" +
                     (topic_wait() == TopicWait::EventLoop ? "event_loop" : "reader_thread") +
                     "\", \"streams\": [";
  {
    std::lock_guard lock(forwarders_mutex);
    for (const Forwarder* forwarder : forwarders) {
      if (text.back() != '[') text += ", ";
      text += "{\"stream\": " + json_string(forwarder->label()) +
              ", \"sent\": " + std::to_string(forwarder->sent()) +
              ", \"dropped\": " + std::to_string(forwarder->dropped()) + "}";
    }
    for (const StatusListing* listing : listings) {
      if (text.back() != '[') text += ", ";
      text += "{\"stream\": " + json_string(listing->label()) +
              ", \"sent\": " + std::to_string(listing->counts().sent.load()) +
              ", \"dropped\": " + std::to_string(listing->counts().dropped.load()) + "}";
    }
  }
  text += "]}\n";
  const std::string partial = path + ".partial";
  if (std::FILE* file = std::fopen(partial.c_str(), "w")) {
    std::fputs(text.c_str(), file);
    std::fclose(file);
    std::rename(partial.c_str(), path.c_str());
  }
}

StatusListing::StatusListing(std::string label, std::shared_ptr<const StreamCounts> counts)
    : label_(std::move(label)), counts_(std::move(counts)) {
  std::lock_guard lock(forwarders_mutex);
  listings.push_back(this);
}

StatusListing::~StatusListing() {
  std::lock_guard lock(forwarders_mutex);
  listings.erase(std::find(listings.begin(), listings.end(), this));
}

std::string address_of(kj::PeerIdentity& identity) {
  if (auto* tls = dynamic_cast<kj::TlsPeerIdentity*>(&identity)) {
    return tls->getNetworkIdentity().toString().cStr();
  }
  return identity.toString().cStr();
}

}  // namespace horus::remote
