// A type-agnostic Cyclone DDS (0.10) sertype whose samples are already-serialized CDR: a 4-byte
// encapsulation header and an XCDR1 body. The bridge encodes and decodes CDR itself (from the
// HORUS schema), so it needs no per-type C struct and no idlc output: any DDS type name works.
#pragma once

#include <cstddef>
#include <string>

#include "dds/dds.h"
#include "dds/ddsi/ddsi_serdata.h"
#include "dds/ddsi/ddsi_sertype.h"

namespace horus::dds_bridge {

// A new sertype named `type_name` (e.g. "horus::msg::dds_::CmdVel_"), keyless; the caller owns
// one reference (dds_create_topic_sertype takes it over).
ddsi_sertype* raw_cdr_sertype(const std::string& type_name);

// A sample holding a copy of `size` bytes of CDR (header included), for dds_writecdr, which
// consumes the reference.
ddsi_serdata* raw_cdr_sample(const ddsi_sertype* type, const void* cdr, std::size_t size);

}  // namespace horus::dds_bridge
