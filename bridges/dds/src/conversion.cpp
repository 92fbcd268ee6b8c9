#include "horus/dds/conversion.hpp"

#include <stdexcept>
#include <string>
#include <utility>

namespace horus::dds_bridge {
namespace {

class PodConversion final : public Conversion {
 public:
  explicit PodConversion(CdrPlan plan) : plan_(std::move(plan)) {}
  void to_dds(std::span<const std::byte> message, std::vector<std::byte>& sample) override {
    plan_.encode(message.data(), sample);  // the local topic takes messages of the POD size only
  }
  std::string to_local(std::span<const std::byte> sample,
                       std::vector<std::byte>& message) override {
    message.resize(plan_.pod_size());
    return plan_.decode(sample, message.data());
  }

 private:
  CdrPlan plan_;
};

class SerializedConversion final : public Conversion {
 public:
  SerializedConversion(std::shared_ptr<const TypeDescription> description, const MessageType& type)
      : description_(std::move(description)), codec_(*description_, type) {}
  void to_dds(std::span<const std::byte> message, std::vector<std::byte>& sample) override {
    codec_.encode({reinterpret_cast<const std::uint8_t*>(message.data()), message.size()}, sample);
  }
  std::string to_local(std::span<const std::byte> sample,
                       std::vector<std::byte>& message) override {
    std::string error = codec_.decode(sample, encoded_);
    const auto* bytes = reinterpret_cast<const std::byte*>(encoded_.data());
    message.assign(bytes, bytes + encoded_.size());
    return error;
  }

 private:
  std::shared_ptr<const TypeDescription> description_;
  SerializedCdr codec_;
  std::vector<std::uint8_t> encoded_;
};

class PoolConversion final : public Conversion {
 public:
  PoolConversion(CdrPlan plan, std::unique_ptr<PoolFrames> frames)
      : plan_(std::move(plan)), frames_(std::move(frames)) {}

  void to_dds(std::span<const std::byte> frame, std::vector<std::byte>& sample) override {
    if (frame.size() < plan_.pod_size()) {
      throw std::invalid_argument("a frame of " + std::to_string(frame.size()) +
                                  " bytes is shorter than its descriptor's " +
                                  std::to_string(plan_.pod_size()));
    }
    plan_.encode(frame.data(), sample, frame.subspan(plan_.pod_size()));
  }

  std::string to_local(std::span<const std::byte> sample,
                       std::vector<std::byte>& message) override {
    recorded_.resize(plan_.pod_size());
    std::string error = plan_.decode(sample, recorded_.data(), &data_);
    if (!error.empty()) {
      return error;
    }
    recorded_.insert(recorded_.end(), data_.begin(), data_.end());
    const std::span<const std::byte> descriptor = frames_->replay(
        {reinterpret_cast<const std::uint8_t*>(recorded_.data()), recorded_.size()});
    if (descriptor.empty()) {
      return "its data does not fit its descriptor";
    }
    message.assign(descriptor.begin(), descriptor.end());
    return {};
  }

 private:
  CdrPlan plan_;
  std::unique_ptr<PoolFrames> frames_;  // makes the imported frames again
  std::vector<std::byte> recorded_;     // a frame: the descriptor, then its block's data
  std::vector<std::byte> data_;
};

}  // namespace

std::unique_ptr<Conversion> pool_conversion(CdrPlan plan, std::unique_ptr<PoolFrames> frames) {
  return std::make_unique<PoolConversion>(std::move(plan), std::move(frames));
}

std::unique_ptr<Conversion> pod_conversion(CdrPlan plan) {
  return std::make_unique<PodConversion>(std::move(plan));
}

std::unique_ptr<Conversion> serialized_conversion(
    std::shared_ptr<const TypeDescription> description, const MessageType& type) {
  return std::make_unique<SerializedConversion>(std::move(description), type);
}

}  // namespace horus::dds_bridge
