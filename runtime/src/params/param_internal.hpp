// The parameter store's file layout and the pieces the store, the owner and the YAML files share
// (README.md in this folder explains the layout and why it is so).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <msgpack/object.hpp>
#include <msgpack/sbuffer.hpp>

#include "horus/detail/shm_access.hpp"
#include "horus/params.hpp"
#include "horus/raw_service.hpp"

namespace horus::detail {

inline constexpr char kParamStoreMagic[8] = {'h', 'o', 'r', 'u', 's', 'p', 'r', 'm'};
inline constexpr std::uint32_t kParamStoreLayout = 1;
inline constexpr std::size_t kParamValueWords = kMaxParamValueBytes / 8;
/// A persisted value is MessagePack: an array of 256 one-byte elements needs a little more.
inline constexpr std::size_t kPersistedWords = 128;
/// Far above any node's parameters; a header claiming more is not a store.
inline constexpr std::uint32_t kMaxParamRecords = 4096;

/// The file's first bytes. Written once by the owner that creates the file, except the atomics.
struct ParamStoreHeader {
  char magic[8];
  std::uint32_t layout;
  std::uint32_t record_count;
  std::uint64_t description_offset;
  std::uint64_t description_size;
  std::uint64_t records_offset;
  std::uint64_t file_size;
  /// The running owner's process identity (detail/process.hpp); 0 while none runs.
  std::atomic<std::uint64_t> owner;
  std::atomic<std::uint64_t> change_count;
  /// The change counter's low half: the futex word wait_for_change() sleeps on.
  std::atomic<std::uint32_t> change_word;
  std::uint32_t reserved;
  /// The owner's program name, NUL-padded (for "already runs in pid N (program)").
  std::atomic<std::uint64_t> owner_program[4];
};

/// One copy of a string's or an array's bytes, under its own sequence number (odd while a
/// writer is in it).
struct ParamBuffer {
  std::atomic<std::uint64_t> sequence;
  std::atomic<std::uint64_t> size;
  std::atomic<std::uint64_t> words[kParamValueWords];
};

/// One parameter's record.
struct ParamRecord {
  /// A scalar's value (detail::param_word_of).
  std::atomic<std::uint64_t> word;
  std::atomic<std::uint64_t> version;
  /// Which buffer holds a string's or array's value.
  std::atomic<std::uint64_t> current;
  /// MessagePack bytes of a value kept for the next start (0: none); written only under the
  /// file's flock.
  std::atomic<std::uint64_t> persisted_size;
  std::atomic<std::uint64_t> persisted[kPersistedWords];
  ParamBuffer buffers[2];
};

static_assert(std::atomic<std::uint64_t>::is_always_lock_free);

/// A mapping of a store file, unmapped when the last user lets go.
struct ParamMapping {
  void* address = nullptr;
  std::size_t size = 0;
  ParamMapping(void* mapped, std::size_t bytes) : address(mapped), size(bytes) {}
  ~ParamMapping();
  ParamMapping(const ParamMapping&) = delete;
  ParamMapping& operator=(const ParamMapping&) = delete;
  ParamStoreHeader& header() const { return *static_cast<ParamStoreHeader*>(address); }
  ParamRecord& record(std::size_t index) const;
};

/// What a valid store holds, checked against the file's size (horus::Error otherwise).
struct ParamStoreView {
  std::shared_ptr<ParamMapping> mapping;
  std::string description_bytes;
  TypeDescription description;
  std::vector<ParamDeclaration> declarations;
};
ParamStoreView view_param_store(std::shared_ptr<ParamMapping> mapping, const std::string& path);

/// The folder <root>/@params/<namespace> (created when `create`; -1 when missing otherwise).
FileDescriptor open_param_folder(const std::string& namespace_name, bool create);
std::string param_store_path(const std::string& namespace_name, const std::string& node);
/// The namespace's name (the current one when empty), checked.
std::string param_namespace(std::string_view namespace_name);
/// Refuses a node name a store cannot have, with the reason.
void check_param_node_name(std::string_view node);

/// One VALUE as text: JSON (param_value_json), or with `yaml` the YAML of a parameter file,
/// which differs only in writing NaN and infinities (.nan, .inf, -.inf).
void append_param_value_text(std::string& out, const msgpack::object& value, bool single_precision,
                             bool yaml);

/// The declarations as a type description (the store's); param_declarations_of() reads them back.
std::string describe_params(std::string_view node, const std::vector<ParamDeclaration>& params);

/// Store values: the current value as MessagePack VALUE bytes; a write (the owner's alone).
std::string read_param_value(const ParamDeclaration& declaration, const ParamRecord& record);
void write_param_value(const ParamDeclaration& declaration, ParamRecord& record,
                       std::string_view value);
/// The bytes of a string's or array's record (never torn).
std::string read_record_bytes(const ParamRecord& record);
/// Counts a change and wakes whoever waits on the store.
void count_param_change(ParamStoreHeader& header);

/// A persisted value (empty: none) and setting / clearing one (under the flock).
std::string persisted_param_value(const ParamRecord& record);
void persist_param_value(ParamRecord& record, std::string_view value);

/// Writes `value` as a MessagePack float64 always (msgpack-cxx's pack_double writes a whole
/// number as an integer), as horus-gen writes floats.
void pack_float64(msgpack::sbuffer& buffer, double value);

bool param_is_scalar(const ParamDeclaration& declaration) noexcept;
std::string param_spelling(const TypeRef& type);
/// The value as the declaration's canonical MessagePack bytes (ParamError when not its type).
std::string canonical_param_value(const ParamDeclaration& declaration, std::string_view value);
/// Why the value does not fit the declaration (type, range, choices, size), or empty.
std::string param_value_problem(const ParamDeclaration& declaration, std::string_view value);

/// The write service of a node's parameters.
RawServiceType param_service_type(std::string_view node);
/// Requests and responses: MessagePack maps inside the service's Vec<u8> payload.
struct ParamWriteRequest {
  std::string name;
  std::string value;
  std::string source;
  std::int64_t timeout_ns = 0;
};
struct ParamWriteResponse {
  ParamSetResult result;
};
std::vector<std::byte> encode_param_request(const ParamWriteRequest& request);
ParamWriteRequest decode_param_request(std::span<const std::byte> payload);
std::vector<std::byte> encode_param_response(const ParamSetResult& result);
ParamSetResult decode_param_response(std::span<const std::byte> payload);

/// A parameter file read and checked: per node, per parameter, the value and its line.
struct ParamFileValue {
  /// The YAML scalar, or the items of a YAML list.
  std::vector<std::string> items;
  bool list = false;
  std::size_t line = 0;
  /// MessagePack VALUE bytes, once checked against the declaration.
  std::string value;
};
struct ParamFile {
  std::string path;
  std::map<std::string, std::map<std::string, ParamFileValue>> nodes;
  std::map<std::string, std::size_t> node_lines;
};
/// Reads the YAML file (ParamError listing every FILE:LINE: reason of its syntax).
ParamFile read_param_file(const std::filesystem::path& path);
/// Checks the file's values against the nodes' declarations; every problem as FILE:LINE: reason
/// (`known_nodes_only`: a node of the file that is not in `declarations` is one).
std::vector<std::string> param_file_problems(
    ParamFile& file,
    const std::map<std::string, const std::vector<ParamDeclaration>*>& declarations,
    bool known_nodes_only);

}  // namespace horus::detail
