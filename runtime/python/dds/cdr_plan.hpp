// A POD message type's CDR (XCDR1, the IDL horus-gen emits) as a list of steps over its struct
// bytes, so a bridge thread turns a HORUS slot into a DDS sample and back with no Python and no
// per-field dispatch on types. dds_cdr.pod_plan (Python, from the generated class's codecs and
// offsets) computes the steps once per type; this side only checks they stay inside the struct.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace horus::dds_bridge {

struct CdrStep {
  enum class Kind : std::uint8_t {
    kCopy,    // `count` numbers of `size` bytes (integers, floats, enums), little-endian in POD
    kBool,    // `count` bools: CDR's octet 0 or 1
    kString,  // string<N> (`size` = N, NUL-padded): CDR's uint32 length with the NUL, bytes, NUL
    kEmpty,   // a message without fields: ROS 2's one uint8 member, nothing in POD
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

  /// The DDS sample of `pod` (pod_size() bytes) into `sample`: the CDR_LE encapsulation header,
  /// the body, padding to a multiple of 4 (the header's options count it), as dds_cdr writes it.
  void encode(const std::byte* pod, std::vector<std::byte>& sample) const;

  /// `pod` (pod_size() bytes) from a DDS sample, little- or big-endian CDR; padding and unused
  /// string bytes zeroed. An empty string when it decoded, else why not (one line).
  std::string decode(std::span<const std::byte> sample, std::byte* pod) const;

 private:
  std::string type_name_;
  std::size_t pod_size_;
  std::vector<CdrStep> steps_;
};

}  // namespace horus::dds_bridge
