// How a carried topic's messages become DDS samples and back, one kind per type: a POD type's
// CdrPlan, a serialized type's SerializedCdr, a pool descriptor's frames (its block's data in
// place of its PoolBlock field: a CdrPlan over the recorded frame out, horus::PoolFrames making
// the frame again in); all from the type description.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "horus/dds/cdr_plan.hpp"
#include "horus/dds/serialized_cdr.hpp"
#include "horus/pool_frames.hpp"
#include "horus/type_description.hpp"

namespace horus::dds_bridge {

class Conversion {
 public:
  virtual ~Conversion() = default;
  /// The sample of a received message's bytes into `sample` (a pool-backed type's: its frame as a
  /// bridge::FrameSource records it, the descriptor then its block's data); throws
  /// std::exception (why) when the message does not encode (it is then dropped, and said).
  virtual void to_dds(std::span<const std::byte> message, std::vector<std::byte>& sample) = 0;
  /// The message of a DDS sample into `message`; why it does not decode, or empty. Throws
  /// std::exception (why) when it decodes but cannot be made here (no pool block to fill).
  virtual std::string to_local(std::span<const std::byte> sample,
                               std::vector<std::byte>& message) = 0;
};

/// A POD type's (the local topic takes messages of plan.pod_size() bytes only).
std::unique_ptr<Conversion> pod_conversion(CdrPlan plan);

/// A serialized type's: the message `type` of `description`, which it keeps.
std::unique_ptr<Conversion> serialized_conversion(
    std::shared_ptr<const TypeDescription> description, const MessageType& type);

/// A pool-backed type's (`plan`: its descriptor's, with pool_data): a recorded frame to a sample,
/// and a sample to a frame made again in a block by `frames`, its PoolFrames in the bridge's
/// namespace.
std::unique_ptr<Conversion> pool_conversion(CdrPlan plan, std::unique_ptr<PoolFrames> frames);

}  // namespace horus::dds_bridge
