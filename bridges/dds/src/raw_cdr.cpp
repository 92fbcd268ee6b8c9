// The raw-CDR sertype (raw_cdr.hpp), after rmw_cyclonedds' serdata: a sample is its bytes.
#include "horus/dds/raw_cdr.hpp"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <string>

#include "dds/ddsi/ddsi_typelib.h"
#include "dds/ddsi/q_radmin.h"  // nn_rdata, to copy a received sample out of its fragments
#include "dds/ddsrt/heap.h"

namespace horus::dds_bridge {
namespace {

struct XTypesData {
  std::string type_info;  // serialized XTypes TypeInformation, empty for none
  std::string type_map;   // and TypeMapping
};

struct RawSertype {
  ddsi_sertype c;  // first: Cyclone's pointer to it is a pointer to this
  XTypesData* types;
};

const XTypesData* types_of(const ddsi_sertype* type) {
  return reinterpret_cast<const RawSertype*>(type)->types;
}

// Cyclone's view of serialized type information: it only reads through the pointer.
ddsi_sertype_cdr_data_t cdr_data(const std::string& bytes) {
  return {static_cast<std::uint32_t>(bytes.size()),
          reinterpret_cast<std::uint8_t*>(const_cast<char*>(bytes.data()))};
}

struct RawSerdata {
  ddsi_serdata c;  // first: Cyclone's pointer to it is a pointer to this
  std::uint32_t size;
  unsigned char* data;
};

// What dds_write/dds_take would exchange with this sertype; the bridge uses writecdr/takecdr,
// but Cyclone may still ask for the sample operations.
struct RawSample {
  unsigned char* buffer;
  std::uint32_t size;
};

RawSerdata* raw(ddsi_serdata* sample) { return reinterpret_cast<RawSerdata*>(sample); }
const RawSerdata* raw(const ddsi_serdata* sample) {
  return reinterpret_cast<const RawSerdata*>(sample);
}

RawSerdata* new_serdata(const ddsi_sertype* type, ddsi_serdata_kind kind, std::size_t size) {
  auto* sample = new RawSerdata{};
  ddsi_serdata_init(&sample->c, type, kind);
  // Cyclone sends sizes rounded up to 4 (the encapsulation options say how many bytes pad).
  const std::size_t padded = (size + 3) & ~std::size_t{3};
  sample->size = static_cast<std::uint32_t>(padded);
  sample->data = new unsigned char[padded == 0 ? 4 : padded]();
  return sample;
}

std::uint32_t get_size(const ddsi_serdata* sample) { return raw(sample)->size; }

void free_serdata(ddsi_serdata* sample) {
  delete[] raw(sample)->data;
  delete raw(sample);
}

bool equal_keys(const ddsi_serdata*, const ddsi_serdata*) { return true; }  // keyless

ddsi_serdata* from_ser(const ddsi_sertype* type, ddsi_serdata_kind kind, const nn_rdata* fragment,
                       std::size_t size) {
  RawSerdata* sample = new_serdata(type, kind, size);
  std::uint32_t offset = 0;
  unsigned char* cursor = sample->data;
  for (; fragment != nullptr; fragment = fragment->nextfrag) {
    if (fragment->maxp1 > offset) {
      const auto* payload = NN_RMSG_PAYLOADOFF(fragment->rmsg, NN_RDATA_PAYLOAD_OFF(fragment));
      std::memcpy(cursor, payload + offset - fragment->min, fragment->maxp1 - offset);
      cursor += fragment->maxp1 - offset;
      offset = fragment->maxp1;
    }
  }
  return &sample->c;
}

ddsi_serdata* from_ser_iov(const ddsi_sertype* type, ddsi_serdata_kind kind,
                           ddsrt_msg_iovlen_t count, const ddsrt_iovec_t* pieces,
                           std::size_t size) {
  RawSerdata* sample = new_serdata(type, kind, size);
  unsigned char* cursor = sample->data;
  for (ddsrt_msg_iovlen_t i = 0; i < count; ++i) {
    std::memcpy(cursor, pieces[i].iov_base, pieces[i].iov_len);
    cursor += pieces[i].iov_len;
  }
  return &sample->c;
}

ddsi_serdata* from_keyhash(const ddsi_sertype* type, const ddsi_keyhash*) {
  RawSerdata* sample = new_serdata(type, SDK_KEY, 4);
  sample->data[1] = 1;  // CDR_LE: a keyless key sample is its header alone
  return &sample->c;
}

ddsi_serdata* from_sample(const ddsi_sertype* type, ddsi_serdata_kind kind, const void* value) {
  if (kind != SDK_DATA) {
    return from_keyhash(type, nullptr);
  }
  const auto* given = static_cast<const RawSample*>(value);
  RawSerdata* sample = new_serdata(type, kind, given->size);
  std::memcpy(sample->data, given->buffer, given->size);
  return &sample->c;
}

void to_ser(const ddsi_serdata* sample, std::size_t offset, std::size_t size, void* out) {
  std::memcpy(out, raw(sample)->data + offset, size);
}

ddsi_serdata* to_ser_ref(const ddsi_serdata* sample, std::size_t offset, std::size_t size,
                         ddsrt_iovec_t* ref) {
  ref->iov_base = raw(sample)->data + offset;
  ref->iov_len = static_cast<ddsrt_iov_len_t>(size);
  return ddsi_serdata_ref(sample);
}

void to_ser_unref(ddsi_serdata* sample, const ddsrt_iovec_t*) { ddsi_serdata_unref(sample); }

bool to_sample(const ddsi_serdata* sample, void* value, void**, void*) {
  auto* out = static_cast<RawSample*>(value);
  delete[] out->buffer;
  out->buffer = new unsigned char[raw(sample)->size == 0 ? 1 : raw(sample)->size];
  std::memcpy(out->buffer, raw(sample)->data, raw(sample)->size);
  out->size = raw(sample)->size;
  return true;
}

ddsi_serdata* to_untyped(const ddsi_serdata* sample) {
  ddsi_serdata* key = from_keyhash(sample->type, nullptr);
  key->type = nullptr;
  return key;
}

bool untyped_to_sample(const ddsi_sertype*, const ddsi_serdata*, void*, void**, void*) {
  return true;
}

std::size_t print(const ddsi_sertype*, const ddsi_serdata* sample, char* out, std::size_t size) {
  return static_cast<std::size_t>(
      std::snprintf(out, size, "(raw cdr %u bytes)", static_cast<unsigned>(raw(sample)->size)));
}

void get_keyhash(const ddsi_serdata*, ddsi_keyhash* out, bool) { std::memset(out, 0, sizeof *out); }

ddsi_serdata_ops make_serdata_ops() {
  ddsi_serdata_ops ops{};
  ops.eqkey = equal_keys;
  ops.get_size = get_size;
  ops.from_ser = from_ser;
  ops.from_ser_iov = from_ser_iov;
  ops.from_keyhash = from_keyhash;
  ops.from_sample = from_sample;
  ops.to_ser = to_ser;
  ops.to_ser_ref = to_ser_ref;
  ops.to_ser_unref = to_ser_unref;
  ops.to_sample = to_sample;
  ops.to_untyped = to_untyped;
  ops.untyped_to_sample = untyped_to_sample;
  ops.free = free_serdata;
  ops.print = print;
  ops.get_keyhash = get_keyhash;
  return ops;
}

const ddsi_serdata_ops serdata_ops = make_serdata_ops();

void free_sertype(ddsi_sertype* type) {
  ddsi_sertype_fini(type);
  auto* own = reinterpret_cast<RawSertype*>(type);
  delete own->types;
  delete own;
}

void zero_samples(const ddsi_sertype*, void* samples, std::size_t count) {
  std::memset(samples, 0, count * sizeof(RawSample));
}

void realloc_samples(void** pointers, const ddsi_sertype*, void* old, std::size_t old_count,
                     std::size_t count) {
  // ddsrt_realloc aborts when memory is exhausted, as Cyclone's own sertypes do.
  auto* samples = static_cast<RawSample*>(ddsrt_realloc(old, count * sizeof(RawSample)));
  for (std::size_t i = old_count; i < count; ++i) {
    samples[i] = RawSample{nullptr, 0};
  }
  for (std::size_t i = 0; i < count; ++i) {
    pointers[i] = &samples[i];
  }
}

void free_samples(const ddsi_sertype*, void** pointers, std::size_t count, dds_free_op_t op) {
  if (count == 0) {
    return;
  }
  if ((op & DDS_FREE_CONTENTS_BIT) != 0) {
    for (std::size_t i = 0; i < count; ++i) {
      auto* sample = static_cast<RawSample*>(pointers[i]);
      delete[] sample->buffer;
      sample->buffer = nullptr;
    }
  }
  if ((op & DDS_FREE_ALL_BIT) != 0) {
    ddsrt_free(pointers[0]);
  }
}

// Cyclone compares type names before calling these.
bool equal_types(const ddsi_sertype* a, const ddsi_sertype* b) {
  return types_of(a)->type_info == types_of(b)->type_info;
}
std::uint32_t hash_type(const ddsi_sertype* type) {
  return static_cast<std::uint32_t>(std::hash<std::string>{}(types_of(type)->type_info));
}

// As Cyclone's default sertype gives the type information idlc put in a topic descriptor.
ddsi_typeinfo_t* type_info(const ddsi_sertype* type) {
  if (types_of(type)->type_info.empty()) {
    return nullptr;
  }
  const ddsi_sertype_cdr_data_t data = cdr_data(types_of(type)->type_info);
  return ddsi_typeinfo_deser(&data);
}

ddsi_typemap_t* type_map(const ddsi_sertype* type) {
  if (types_of(type)->type_map.empty()) {
    return nullptr;
  }
  const ddsi_sertype_cdr_data_t data = cdr_data(types_of(type)->type_map);
  return ddsi_typemap_deser(&data);
}

ddsi_typeid_t* type_id(const ddsi_sertype* type, ddsi_typeid_kind_t kind) {
  ddsi_typeinfo_t* info = type_info(type);
  if (info == nullptr) {
    return nullptr;
  }
  ddsi_typeid_t* id = ddsi_typeinfo_typeid(info, kind);
  ddsi_typeinfo_fini(info);
  ddsrt_free(info);
  return id;
}

std::size_t serialized_size(const ddsi_sertype*, const void* value) {
  return static_cast<const RawSample*>(value)->size;
}

bool serialize_into(const ddsi_sertype*, const void* value, void* out, std::size_t size) {
  const auto* sample = static_cast<const RawSample*>(value);
  if (size < sample->size) {
    return false;
  }
  std::memcpy(out, sample->buffer, sample->size);
  return true;
}

ddsi_sertype_ops make_sertype_ops() {
  ddsi_sertype_ops ops{};
  ops.version = ddsi_sertype_v0;
  ops.free = free_sertype;
  ops.zero_samples = zero_samples;
  ops.realloc_samples = realloc_samples;
  ops.free_samples = free_samples;
  ops.equal = equal_types;
  ops.hash = hash_type;
  ops.type_id = type_id;
  ops.type_map = type_map;
  ops.type_info = type_info;
  ops.get_serialized_size = serialized_size;
  ops.serialize_into = serialize_into;
  return ops;
}

const ddsi_sertype_ops sertype_ops = make_sertype_ops();

}  // namespace

ddsi_sertype* raw_cdr_sertype(const std::string& type_name, const std::string& type_info,
                              const std::string& type_map) {
  auto types = std::make_unique<XTypesData>(XTypesData{type_info, type_map});
  auto* type = new RawSertype{{}, types.release()};
  ddsi_sertype_init_flags(&type->c, type_name.c_str(), &sertype_ops, &serdata_ops,
                          DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  return &type->c;
}

ddsi_serdata* raw_cdr_sample(const ddsi_sertype* type, const void* cdr, std::size_t size) {
  ddsrt_iovec_t piece{};
  piece.iov_base = const_cast<void*>(cdr);
  piece.iov_len = static_cast<ddsrt_iov_len_t>(size);
  return ddsi_serdata_from_ser_iov(type, SDK_DATA, 1, &piece, size);
}

std::span<const std::byte> raw_cdr_bytes(const ddsi_serdata* sample) {
  return {reinterpret_cast<const std::byte*>(raw(sample)->data), raw(sample)->size};
}

std::string guid_hex(const dds_guid_t& guid) {
  static constexpr char digits[] = "0123456789abcdef";
  std::string out;
  for (const auto byte : guid.v) {
    out += digits[byte >> 4];
    out += digits[byte & 15];
  }
  return out;
}

std::string writer_guid(dds_entity_t reader, dds_instance_handle_t handle) {
  dds_builtintopic_endpoint_t* writer = dds_get_matched_publication_data(reader, handle);
  if (writer == nullptr) {
    return "unknown";
  }
  std::string guid = guid_hex(writer->key);
  dds_builtintopic_free_endpoint(writer);
  return guid;
}

}  // namespace horus::dds_bridge
