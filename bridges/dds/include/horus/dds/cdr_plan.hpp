// A POD message type's CDR (XCDR1, the IDL horus-gen emits) as a list of steps over its struct
// bytes, so a bridge thread turns a HORUS slot into a DDS sample and back with no per-field
// dispatch on types. pod_cdr_plan() computes the steps once per type from the type description's
// field offsets (horus/type_description.hpp); the plan checks they stay inside the struct.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "horus/type_description.hpp"

namespace horus::dds_bridge {

struct CdrStep {
  enum class Kind : std::uint8_t {
    kCopy,      // `count` numbers of `size` bytes (integers, floats, enums), little-endian in POD
    kBool,      // `count` bools: CDR's octet 0 or 1
    kString,    // string<N> (`size` = N, NUL-padded): CDR's uint32 length with the NUL, bytes, NUL
    kEmpty,     // a message without fields: ROS 2's one uint8 member, nothing in POD
    kPoolData,  // a pool descriptor's PoolBlock field: the block's data as sequence<uint8>
  };
  Kind kind;
  std::uint32_t offset;  // in the POD struct
  std::uint32_t size;
  std::uint32_t count;
};

class CdrPlan {
 public:
  /// Throws std::invalid_argument when a step reaches outside `pod_size` bytes or has a size CDR
  /// has no primitive of.
  CdrPlan(std::string type_name, std::size_t pod_size, std::vector<CdrStep> steps);

  const std::string& type_name() const noexcept { return type_name_; }
  std::size_t pod_size() const noexcept { return pod_size_; }
  const std::vector<CdrStep>& steps() const noexcept { return steps_; }

  /// The DDS sample of `pod` (pod_size() bytes) into `sample`: the CDR_LE encapsulation header,
  /// the body, padding to a multiple of 4 (the header's options count it), as dds_cdr writes it.
  /// `pool_data`: the block's data a kPoolData step writes (a recorded frame's bytes after the
  /// descriptor). `body_prefix`: bytes the body starts with, the members of an enclosing message
  /// before this one (a ROS 2 action's GetResult response puts its status first), after which
  /// this message's members align as CDR counts it, from the body's start.
  void encode(const std::byte* pod, std::vector<std::byte>& sample,
              std::span<const std::byte> pool_data = {},
              std::span<const std::byte> body_prefix = {}) const;

  /// `pod` (pod_size() bytes) from a DDS sample, little- or big-endian CDR; padding and unused
  /// string bytes zeroed. An empty string when it decoded, else why not (one line).
  /// A kPoolData step's data goes to `pool_data` (the step's field stays zero). `body_prefix`:
  /// how many bytes of the body come before this message's members (encode's body_prefix).
  std::string decode(std::span<const std::byte> sample, std::byte* pod,
                     std::vector<std::byte>* pool_data = nullptr,
                     std::size_t body_prefix = 0) const;

 private:
  std::string type_name_;
  std::size_t pod_size_;
  std::vector<CdrStep> steps_;
};

/// Why a DDS sample is not one the bridge reads (no encapsulation header, XCDR2, not plain CDR),
/// or empty when it is; `big_endian` then says its byte order.
std::string encapsulation_error(std::span<const std::byte> sample, bool& big_endian);

/// The plan of the POD message `type` of `description`, in CDR order: numbers and enums copied,
/// bools, string<N>; a message without fields is ROS 2's one octet. Neighbouring numbers of one
/// size are one step. `pool_data`: a field of horus.msg.PoolBlock is a kPoolData step (a pool
/// descriptor crossing with its block's data). Throws std::invalid_argument for a serialized
/// message.
CdrPlan pod_cdr_plan(const TypeDescription& description, const MessageType& type,
                     bool pool_data = false);

}  // namespace horus::dds_bridge
