// A type-agnostic Cyclone DDS (0.10) sertype whose samples are already-serialized CDR: a 4-byte
// encapsulation header and an XCDR1 body. The bridge encodes and decodes CDR itself (from the
// HORUS schema), so it needs no per-type C struct: any DDS type name works. What it cannot know
// by itself is the type's XTypes type information, which DDS matches readers and writers by: the
// caller passes it (the TypeInformation and TypeMapping idlc makes of the type's IDL), or none.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "dds/dds.h"
#include "dds/ddsi/ddsi_serdata.h"
#include "dds/ddsi/ddsi_sertype.h"

namespace horus::dds_bridge {

// A new sertype named `type_name` (e.g. "horus::msg::dds_::CmdVel_"), keyless, announcing the
// serialized XTypes TypeInformation `type_info` and TypeMapping `type_map` (both empty: none); the
// caller owns one reference (dds_create_topic_sertype takes it over).
ddsi_sertype* raw_cdr_sertype(const std::string& type_name, const std::string& type_info,
                              const std::string& type_map);

// A sample holding a copy of `size` bytes of CDR (header included), for dds_writecdr, which
// consumes the reference.
ddsi_serdata* raw_cdr_sample(const ddsi_sertype* type, const void* cdr, std::size_t size);

// The bytes of a sample of a raw-CDR sertype (header included), valid while it is referenced.
std::span<const std::byte> raw_cdr_bytes(const ddsi_serdata* sample);

// The GUID of `guid` in hex, as the bridge names writers and participants.
std::string guid_hex(const dds_guid_t& guid);

// The GUID (hex) of the writer `reader` matches under `handle` (a sample's publication_handle),
// or "unknown" once DDS no longer knows it.
std::string writer_guid(dds_entity_t reader, dds_instance_handle_t handle);

// Takes every sample `reader` (of a raw-CDR topic) holds, oldest first, calling `each` with the
// bytes of each one with data and the instance handle of the writer that wrote it; DDS's return
// code of a take that failed, else 0.
template <class Each>
dds_return_t take_raw_cdr(dds_entity_t reader, Each&& each) {
  constexpr std::uint32_t kBatch = 64;
  ddsi_serdata* samples[kBatch];
  dds_sample_info_t infos[kBatch];
  for (;;) {
    const dds_return_t count = dds_takecdr(reader, samples, kBatch, infos, DDS_ANY_STATE);
    if (count < 0) {
      return count;
    }
    for (dds_return_t i = 0; i < count; ++i) {
      if (infos[i].valid_data) {
        each(raw_cdr_bytes(samples[i]), infos[i].publication_handle);
      }
      ddsi_serdata_unref(samples[i]);  // takecdr hands out one reference per sample
    }
    if (count < static_cast<dds_return_t>(kBatch)) {
      return 0;
    }
  }
}

}  // namespace horus::dds_bridge
