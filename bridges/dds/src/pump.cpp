#include "horus/dds/pump.hpp"

#include <memory>
#include <optional>
#include <stdexcept>
#include <utility>

#include "horus/dds/raw_cdr.hpp"

namespace horus::dds_bridge {
namespace {

TopicOptions options_of(const LocalTopic& local) {
  TopicOptions options;
  options.capacity = local.capacity;
  options.max_message_size = local.max_message_size;
  options.namespace_name = local.namespace_name;
  options.single_publisher = local.single_publisher;
  return options;
}

TypeIdentity type_of(const LocalTopic& local) {
  return {
      local.type_name, local.fingerprint, local.schema, local.is_pod, local.is_pod ? local.size : 0,
      local.alignment, local.description};
}

RawTopic open_local(const LocalTopic& local) {
  return {local.name, type_of(local), options_of(local)};
}

}  // namespace

std::string DropReport::dropped(const std::string* writer, const std::string& reason,
                                std::uint64_t failure, std::chrono::steady_clock::time_point now) {
  if (writer != nullptr) {
    std::string kind;
    for (const char c : reason) {
      const bool digit = c >= '0' && c <= '9';
      if (!digit) {
        kind += c;
      } else if (kind.empty() || kind.back() != '#') {
        kind += '#';
      }
    }
    std::pair key{*writer, std::move(kind)};
    if (said_.contains(key)) {
      ++unsaid_;
      return due(failure, now);
    }
    if (said_.size() < cap_) {
      said_.insert(std::move(key));
      last_line_ = now;
      return "a DDS sample from writer " + *writer + " " + reason + " (failure " +
             std::to_string(failure) +
             " of it); dropped it, and more of the same from that writer are counted, not said";
    }
  }
  if (!full_said_) {
    full_said_ = true;
    last_line_ = now;
    return "a DDS sample " + reason + " (failure " + std::to_string(failure) +
           " of it); dropped it: this topic has said " + std::to_string(cap_) +
           " writers and reasons, its most, so the samples of others are counted as other "
           "writers', not said";
  }
  ++others_;
  return due(failure, now);
}

std::string DropReport::due(std::uint64_t failures, std::chrono::steady_clock::time_point now) {
  if ((unsaid_ == 0 && others_ == 0) || now - last_line_ < kEvery) {
    return {};
  }
  std::string line = "dropped " + std::to_string(unsaid_ + others_) + " more DDS samples";
  if (others_ == 0) {
    line += " for reasons said before";
  } else {
    line += ", " + std::to_string(unsaid_) + " for reasons said before and " +
            std::to_string(others_) + " of other writers";
  }
  line += " (" + std::to_string(failures) + " failures of it so far)";
  unsaid_ = 0;
  others_ = 0;
  last_line_ = now;
  return line;
}

const std::string* WriterGuids::find(dds_entity_t reader, dds_instance_handle_t writer) {
  const auto known = guids_.find(writer);
  if (known != guids_.end()) {
    return &known->second;
  }
  if (guids_.size() >= cap_) {
    return nullptr;
  }
  return &guids_.emplace(writer, writer_guid(reader, writer)).first->second;
}

ExportPump::ExportPump(const LocalTopic& local, std::unique_ptr<Conversion> conversion,
                       dds_entity_t writer, const ddsi_sertype* type, std::string dds_topic,
                       bool latched, std::string label, std::shared_ptr<void> keep_alive)
    : Forwarder(std::move(label), std::move(keep_alive)),
      local_(std::make_unique<RawTopic>(local.name, type_of(local), options_of(local)),
             local.namespace_name),
      conversion_(std::move(conversion)),
      writer_(writer),
      type_(type),
      dds_topic_(std::move(dds_topic)),
      latched_(latched) {
  start([this] { loop(); });
}

void ExportPump::loop() {
  // A latched topic's last message, sent before this handle opened, is what a late joiner on DDS
  // should get; one that arrived since is taken below anyway.
  if (latched_) {
    if (const std::optional<bridge::Frame> frame = local_.latest()) {
      send_to_dds(frame->bytes);
    }
  }
  while (!stopping()) {
    const std::optional<bridge::Frame> frame = local_.next(kPoll);
    say_stale_frames();  // skipped before this frame
    if (frame) {
      send_to_dds(frame->bytes);
    }
  }
}

void ExportPump::say_stale_frames() {
  for (; stale_said_ < local_.stale(); ++stale_said_) {
    failed(
        "a message does not encode as CDR: its pool block was freed or reused before the bridge "
        "read it",
        "dropped it");
  }
}

void ExportPump::send_to_dds(std::span<const std::byte> frame) {
  try {
    conversion_->to_dds(frame, sample_);
  } catch (const std::exception& error) {  // a message of another process that does not encode
    failed(std::string("a message does not encode as CDR: ") + error.what(), "dropped it");
    return;
  }
  while (!stopping()) {
    // dds_writecdr consumes the reference: a retry makes the sample again.
    const dds_return_t code =
        dds_writecdr(writer_, raw_cdr_sample(type_, sample_.data(), sample_.size()));
    if (code >= 0) {
      count_carried();
      return;
    }
    failed("cannot write to DDS topic '" + dds_topic_ + "': " + dds_strretcode(code),
           "writing the same message again");
    pause();
  }
}

ImportPump::ImportPump(const LocalTopic& local, std::unique_ptr<Conversion> conversion,
                       dds_entity_t reader, std::string dds_topic, std::string label,
                       std::shared_ptr<void> keep_alive, std::size_t drop_cap)
    : Forwarder(std::move(label), std::move(keep_alive)),
      local_(open_local(local)),
      conversion_(std::move(conversion)),
      reader_(reader),
      dds_topic_(std::move(dds_topic)),
      drops_(drop_cap),
      writers_(drop_cap) {
  start([this] { loop(); });
  dds_listener_t* listener = dds_create_listener(this);
  dds_lset_data_available(listener, [](dds_entity_t, void* arg) {
    auto* pump = static_cast<ImportPump*>(arg);
    if (!pump->stopping()) {
      pump->guarded([pump] { pump->drain(); });
    }
  });
  const dds_return_t code = dds_set_listener(reader_, listener);  // copies it
  dds_delete_listener(listener);
  if (code < 0) {
    stop();  // before the members the thread uses are unwound
    throw std::runtime_error("cannot listen on DDS topic '" + dds_topic_ +
                             "': " + dds_strretcode(code));
  }
}

ImportPump::~ImportPump() {
  dds_set_listener(reader_, nullptr);  // returns once no call of the listener runs
  stop();
}

void ImportPump::loop() {
  // Samples that arrived before the listener was set, or that a failed take left.
  while (!stopping()) {
    pause(drain() ? kPoll : kRetry);
  }
  // What was dropped and not said yet, however recently the last line went.
  const std::lock_guard lock(draining_);
  say(drops_.due(failures(), std::chrono::steady_clock::time_point::max()));
}

bool ImportPump::drain() {
  const std::lock_guard lock(draining_);
  const dds_return_t code =
      take_raw_cdr(reader_, [this](std::span<const std::byte> sample,
                                   dds_instance_handle_t writer) { deliver(sample, writer); });
  say(drops_.due(failures(), std::chrono::steady_clock::now()));
  if (code < 0) {
    failed("cannot take from DDS topic '" + dds_topic_ + "': " + dds_strretcode(code), "retrying");
    return false;
  }
  return true;
}

void ImportPump::deliver(std::span<const std::byte> sample, dds_instance_handle_t writer) {
  std::string error;
  try {
    error = conversion_->to_local(sample, message_);
  } catch (const std::exception& failure) {  // decoded, but not to be made here (no pool block)
    drop(writer, std::string("cannot be made here: ") + failure.what());
    return;
  }
  if (!error.empty()) {
    drop(writer, "does not decode: " + error);
  } else if (!local_.send(message_)) {
    drop(writer, "was refused by the local topic (no room, or a stalled publisher)");
  } else {
    count_carried();
  }
}

void ImportPump::drop(dds_instance_handle_t writer, const std::string& reason) {
  say(drops_.dropped(writers_.find(reader_, writer), reason, count_failure(),
                     std::chrono::steady_clock::now()));
}

}  // namespace horus::dds_bridge
