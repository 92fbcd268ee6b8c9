// The parameter store's files and records, the reader every process uses, and writes through
// the owner (set_param). README.md in this folder explains the layout.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>
#include <optional>
#include <thread>

#include "../types/msgpack_input.hpp"
#include "horus/codec.hpp"
#include "horus/detail/futex.hpp"
#include "horus/detail/process.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/internal/namespace_objects.hpp"
#include "horus/plain_value.hpp"
#include "horus/scheduler.hpp"
#include "param_internal.hpp"

namespace horus {
namespace detail {
namespace {

constexpr const char* kParamsFolder = "@params";

std::string node_and_namespace(std::string_view node, const std::string& namespace_name) {
  return "node '" + std::string(node) + "' (namespace '" + namespace_name + "')";
}

/// Copies `size` bytes of atomic words out (each word read relaxed: the sequence numbers order
/// them).
std::string copy_words(const std::atomic<std::uint64_t>* words, std::size_t size) {
  std::string bytes(size, '\0');
  for (std::size_t i = 0; i * 8 < size; ++i) {
    const std::uint64_t word = words[i].load(std::memory_order_relaxed);
    std::memcpy(bytes.data() + i * 8, &word, std::min<std::size_t>(8, size - i * 8));
  }
  return bytes;
}

void store_words(std::atomic<std::uint64_t>* words, std::string_view bytes) {
  for (std::size_t i = 0; i * 8 < bytes.size(); ++i) {
    std::uint64_t word = 0;
    std::memcpy(&word, bytes.data() + i * 8, std::min<std::size_t>(8, bytes.size() - i * 8));
    words[i].store(word, std::memory_order_relaxed);
  }
}

std::string closest_names(std::string_view name, const std::vector<ParamDeclaration>& params) {
  std::vector<std::pair<std::size_t, std::string>> scored;
  for (const ParamDeclaration& each : params) {
    std::size_t common = 0;
    while (common < std::min(name.size(), each.name.size()) && name[common] == each.name[common]) {
      ++common;
    }
    const bool contains = each.name.find(name) != std::string::npos ||
                          (!each.name.empty() && name.find(each.name) != std::string_view::npos);
    scored.emplace_back(contains ? 1000 : common, each.name);
  }
  std::stable_sort(scored.begin(), scored.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string text;
  for (std::size_t i = 0; i < scored.size() && i < 3; ++i) {
    text += (text.empty() ? "" : ", ") + scored[i].second;
  }
  return text.empty() ? "it declares none" : "it has " + text;
}

}  // namespace

ParamMapping::~ParamMapping() {
  if (address != nullptr) ::munmap(address, size);
}

ParamRecord& ParamMapping::record(std::size_t index) const {
  const ParamStoreHeader& top = header();
  return reinterpret_cast<ParamRecord*>(static_cast<char*>(address) + top.records_offset)[index];
}

std::string param_namespace(std::string_view namespace_name) {
  std::string name = namespace_name.empty() ? current_namespace() : std::string(namespace_name);
  validate_segment_name("namespace", name);
  return name;
}

void check_param_node_name(std::string_view node) {
  bool valid = !node.empty() && node.size() <= 200 && node != "." && node != "..";
  for (const char c : node) {
    valid = valid && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '.' || c == '-');
  }
  if (!valid) {
    throw ParamError("node name '" + std::string(node) +
                     "' cannot have parameters: its store is named after it, so use 1 to 200 of "
                     "[A-Za-z0-9_.-] (and not . or ..)");
  }
}

std::string param_store_path(const std::string& namespace_name, const std::string& node) {
  return shm_root() + "/" + kParamsFolder + "/" + namespace_name + "/" + node;
}

FileDescriptor open_param_folder(const std::string& namespace_name, bool create) {
  const std::string root = shm_root();
  const FileDescriptor root_folder =
      open_trusted_directory(AT_FDCWD, root, root, 0600, true, false, create);
  if (root_folder.get() < 0) return FileDescriptor();
  const std::string params_path = root + "/" + kParamsFolder;
  const FileDescriptor params = open_trusted_directory(root_folder.get(), kParamsFolder,
                                                       params_path, 0600, false, false, create);
  if (params.get() < 0) return FileDescriptor();
  return open_trusted_directory(params.get(), namespace_name, params_path + "/" + namespace_name,
                                0600, false, false, create);
}

ParamStoreView view_param_store(std::shared_ptr<ParamMapping> mapping, const std::string& path) {
  const auto refuse = [&path](const std::string& why) {
    throw Error("parameter store " + path + " is not valid: " + why);
  };
  if (mapping->size < sizeof(ParamStoreHeader)) refuse("it is shorter than its header");
  const ParamStoreHeader& header = mapping->header();
  if (std::memcmp(header.magic, kParamStoreMagic, sizeof kParamStoreMagic) != 0) {
    refuse("it is not a HORUS parameter store");
  }
  if (header.layout != kParamStoreLayout) {
    refuse("layout " + std::to_string(header.layout) + " is not this runtime's " +
           std::to_string(kParamStoreLayout));
  }
  if (header.file_size != mapping->size) refuse("its header gives another size than the file's");
  if (header.record_count > kMaxParamRecords) refuse("it claims too many records");
  if (header.description_offset < sizeof(ParamStoreHeader) ||
      header.description_offset > mapping->size ||
      header.description_size > mapping->size - header.description_offset) {
    refuse("its description lies outside the file");
  }
  if (header.records_offset % alignof(ParamRecord) != 0 || header.records_offset > mapping->size ||
      header.record_count * sizeof(ParamRecord) > mapping->size - header.records_offset) {
    refuse("its records lie outside the file");
  }
  ParamStoreView view;
  view.description_bytes.assign(
      static_cast<const char*>(mapping->address) + header.description_offset,
      header.description_size);
  try {
    view.description = TypeDescription::decode(view.description_bytes);
    view.declarations = param_declarations_of(view.description);
  } catch (const Error& e) {
    refuse(e.what());
  }
  if (view.declarations.size() != header.record_count) {
    refuse("it has " + std::to_string(header.record_count) + " records for " +
           std::to_string(view.declarations.size()) + " parameters");
  }
  view.mapping = std::move(mapping);
  return view;
}

std::string describe_params(std::string_view node, const std::vector<ParamDeclaration>& params) {
  TypeDescription description;
  description.version = kTypeDescriptionVersion;
  MessageType message;
  message.name = "horus_params." + std::string(node);
  message.package = "horus_params";
  message.fingerprint = fnv1a(node);
  description.root = message.name;
  for (const ParamDeclaration& param : params) {
    MessageField field;
    field.name = param.name;
    field.type = param.type;
    if (param.enumeration) {
      auto found =
          std::find_if(description.enums.begin(), description.enums.end(),
                       [&](const EnumType& e) { return e.name == param.enumeration->name; });
      field.type.index = static_cast<std::size_t>(found - description.enums.begin());
      if (found == description.enums.end()) description.enums.push_back(*param.enumeration);
    }
    field.default_value = param.default_value;
    field.unit = param.unit;
    field.spelling = param.spelling;
    if (!param.doc.empty()) field.doc = param.doc;
    if (param.min || param.max) field.range = MessageField::Range{param.min, param.max};
    if (!param.choices.empty()) field.choices = param.choices;
    if (param.read_only) field.read_only = true;
    message.fields.push_back(std::move(field));
  }
  description.messages.push_back(std::move(message));
  return description.encode();
}

}  // namespace detail

std::vector<ParamDeclaration> param_declarations_of(const TypeDescription& description) {
  using detail::param_spelling;
  std::vector<ParamDeclaration> params;
  for (const MessageField& field : description.root_message().fields) {
    ParamDeclaration param;
    param.name = field.name;
    param.type = field.type;
    param.spelling = field.spelling.empty() ? param_spelling(field.type) : field.spelling;
    if (field.type.kind == TypeRef::Kind::Enum) {
      param.enumeration = description.enumeration(field.type);
    } else if (field.type.kind != TypeRef::Kind::Primitive &&
               field.type.kind != TypeRef::Kind::String &&
               !(field.type.kind == TypeRef::Kind::Array &&
                 field.type.element->kind == TypeRef::Kind::Primitive &&
                 field.type.length * primitive_size(field.type.element->primitive) <=
                     kMaxParamValueBytes)) {
      throw ParamError("parameter '" + field.name + "' has a type a parameter cannot have");
    }
    param.default_value = field.default_value;
    param.unit = field.unit;
    param.doc = field.doc.value_or("");
    if (field.range) {
      param.min = field.range->min;
      param.max = field.range->max;
    }
    param.choices = field.choices.value_or(std::vector<std::string>{});
    param.read_only = field.read_only.value_or(false);
    params.push_back(std::move(param));
  }
  return params;
}

namespace detail {

std::string read_record_bytes(const ParamRecord& record) {
  std::chrono::steady_clock::time_point started;
  for (std::uint64_t attempt = 0;; ++attempt) {
    const ParamBuffer& buffer = record.buffers[record.current.load(std::memory_order_acquire) & 1];
    const std::uint64_t before = buffer.sequence.load(std::memory_order_acquire);
    if ((before & 1) == 0) {
      const std::size_t size =
          std::min<std::uint64_t>(buffer.size.load(std::memory_order_relaxed), kMaxParamValueBytes);
      // Into words on the stack first, and into a string only once whole: a read is then a few
      // loads and one short copy (a parameter read in a loop must cost about a plain read).
      std::uint64_t words[kParamValueWords];
      for (std::size_t i = 0; i * 8 < size; ++i) {
        words[i] = buffer.words[i].load(std::memory_order_relaxed);
      }
      std::atomic_thread_fence(std::memory_order_acquire);
      if (buffer.sequence.load(std::memory_order_relaxed) == before) {
        return std::string(reinterpret_cast<const char*>(words), size);
      }
    }
    // A writer two values ahead is in the buffer this reader chose: read the other one. A
    // writer finishes in microseconds; a record that stays odd for a second is not a store's.
    if (attempt > 64) std::this_thread::yield();
    if (attempt % 4096 == 4095) {
      if (attempt == 4095) started = std::chrono::steady_clock::now();
      if (std::chrono::steady_clock::now() - started > std::chrono::seconds(1)) {
        throw Error("parameter record is never complete: the store is damaged");
      }
    }
  }
}

std::string read_param_value(const ParamDeclaration& declaration, const ParamRecord& record) {
  if (param_is_scalar(declaration)) {
    return encode_param_word(declaration, record.word.load(std::memory_order_acquire));
  }
  return encode_param_bytes(declaration, read_record_bytes(record));
}

void write_param_value(const ParamDeclaration& declaration, ParamRecord& record,
                       std::string_view value) {
  if (param_is_scalar(declaration)) {
    record.word.store(decode_param_word(declaration, value), std::memory_order_release);
    return;
  }
  const std::string bytes = decode_param_bytes(declaration, value);
  const std::uint64_t next = (record.current.load(std::memory_order_relaxed) & 1) ^ 1;
  ParamBuffer& buffer = record.buffers[next];
  // Odd while writing; a writer killed here leaves it odd, and the other buffer current.
  const std::uint64_t sequence = buffer.sequence.load(std::memory_order_relaxed) | 1;
  buffer.sequence.store(sequence, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  buffer.size.store(bytes.size(), std::memory_order_relaxed);
  store_words(buffer.words, bytes);
  buffer.sequence.store(sequence + 1, std::memory_order_release);
  record.current.store(next, std::memory_order_release);
}

void count_param_change(ParamStoreHeader& header) {
  header.change_count.fetch_add(1, std::memory_order_acq_rel);
  header.change_word.fetch_add(1, std::memory_order_acq_rel);
  futex_wake_all(header.change_word);
}

std::string persisted_param_value(const ParamRecord& record) {
  const std::size_t size = std::min<std::uint64_t>(
      record.persisted_size.load(std::memory_order_acquire), kPersistedWords * 8);
  return copy_words(record.persisted, size);
}

void persist_param_value(ParamRecord& record, std::string_view value) {
  if (value.size() > kPersistedWords * 8) throw ParamError("a persisted value is too large");
  store_words(record.persisted, value);
  record.persisted_size.store(value.size(), std::memory_order_release);
}

RawServiceType param_service_type(std::string_view node) {
  RawServiceType type;
  type.name = param_service_name(node);
  type.request_topic = type.name + ".request";
  type.response_topic = type.name + ".response";
  type.request = type_identity<std::vector<std::uint8_t>>();
  type.response = type.request;
  type.fingerprint = fnv1a("horus_params.write 1");
  const std::vector<std::uint8_t> empty = encode(std::vector<std::uint8_t>{});
  type.empty_request.assign(reinterpret_cast<const std::byte*>(empty.data()),
                            reinterpret_cast<const std::byte*>(empty.data()) + empty.size());
  type.empty_response = type.empty_request;
  return type;
}

namespace {

void pack_text(msgpack::packer<msgpack::sbuffer>& packer, std::string_view text) {
  packer.pack_str(static_cast<std::uint32_t>(text.size()));
  packer.pack_str_body(text.data(), static_cast<std::uint32_t>(text.size()));
}

std::vector<std::byte> wrapped(const msgpack::sbuffer& body) {
  const std::vector<std::uint8_t> bytes(
      reinterpret_cast<const std::uint8_t*>(body.data()),
      reinterpret_cast<const std::uint8_t*>(body.data()) + body.size());
  const std::vector<std::uint8_t> payload = encode(bytes);
  return std::vector<std::byte>(
      reinterpret_cast<const std::byte*>(payload.data()),
      reinterpret_cast<const std::byte*>(payload.data()) + payload.size());
}

/// The map inside a payload, by key.
std::map<std::string, msgpack::object> unwrapped(std::span<const std::byte> payload,
                                                 msgpack::object_handle& handle) {
  const auto bytes = decode<std::vector<std::uint8_t>>(std::span<const std::uint8_t>(
      reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()));
  handle = types::unpack_whole<ParamError>(reinterpret_cast<const char*>(bytes.data()),
                                           bytes.size(), "parameter write");
  const msgpack::object& top = handle.get();
  if (top.type != msgpack::type::MAP) throw ParamError("parameter write: not a map");
  std::map<std::string, msgpack::object> entries;
  for (std::uint32_t i = 0; i < top.via.map.size; ++i) {
    const msgpack::object_kv& entry = top.via.map.ptr[i];
    if (entry.key.type == msgpack::type::STR) {
      entries[std::string(entry.key.via.str.ptr, entry.key.via.str.size)] = entry.val;
    }
  }
  return entries;
}

std::string text_entry(const std::map<std::string, msgpack::object>& entries,
                       const std::string& key) {
  const auto found = entries.find(key);
  if (found == entries.end() || found->second.type != msgpack::type::STR) return {};
  return std::string(found->second.via.str.ptr, found->second.via.str.size);
}

std::string bin_entry(const std::map<std::string, msgpack::object>& entries,
                      const std::string& key) {
  const auto found = entries.find(key);
  if (found == entries.end() || found->second.type != msgpack::type::BIN) return {};
  return std::string(found->second.via.bin.ptr, found->second.via.bin.size);
}

std::uint64_t number_entry(const std::map<std::string, msgpack::object>& entries,
                           const std::string& key) {
  const auto found = entries.find(key);
  if (found == entries.end() || found->second.type != msgpack::type::POSITIVE_INTEGER) return 0;
  return found->second.via.u64;
}

}  // namespace

std::vector<std::byte> encode_param_request(const ParamWriteRequest& request) {
  msgpack::sbuffer body;
  msgpack::packer<msgpack::sbuffer> packer(body);
  packer.pack_map(4);
  pack_text(packer, "name");
  pack_text(packer, request.name);
  pack_text(packer, "value");
  packer.pack_bin(static_cast<std::uint32_t>(request.value.size()));
  packer.pack_bin_body(request.value.data(), static_cast<std::uint32_t>(request.value.size()));
  pack_text(packer, "source");
  pack_text(packer, request.source);
  pack_text(packer, "timeout_ns");
  packer.pack_uint64(static_cast<std::uint64_t>(std::max<std::int64_t>(request.timeout_ns, 0)));
  return wrapped(body);
}

ParamWriteRequest decode_param_request(std::span<const std::byte> payload) {
  msgpack::object_handle handle;
  const auto entries = unwrapped(payload, handle);
  return ParamWriteRequest{text_entry(entries, "name"), bin_entry(entries, "value"),
                           text_entry(entries, "source"),
                           static_cast<std::int64_t>(number_entry(entries, "timeout_ns"))};
}

std::vector<std::byte> encode_param_response(const ParamSetResult& result) {
  msgpack::sbuffer body;
  msgpack::packer<msgpack::sbuffer> packer(body);
  packer.pack_map(3);
  pack_text(packer, "accepted");
  if (result.accepted) {
    packer.pack_true();
  } else {
    packer.pack_false();
  }
  pack_text(packer, "reason");
  pack_text(packer, result.reason);
  pack_text(packer, "version");
  packer.pack_uint64(result.version);
  return wrapped(body);
}

ParamSetResult decode_param_response(std::span<const std::byte> payload) {
  msgpack::object_handle handle;
  const auto entries = unwrapped(payload, handle);
  ParamSetResult result;
  const auto accepted = entries.find("accepted");
  result.accepted = accepted != entries.end() && accepted->second.type == msgpack::type::BOOLEAN &&
                    accepted->second.via.boolean;
  result.reason = text_entry(entries, "reason");
  result.version = number_entry(entries, "version");
  return result;
}

std::vector<NamespaceObjectInfo> param_store_objects(std::string_view namespace_name) {
  const std::string name = param_namespace(namespace_name);
  const FileDescriptor folder = open_param_folder(name, false);
  std::vector<NamespaceObjectInfo> objects;
  if (folder.get() < 0) return objects;
  const std::string folder_path = shm_root() + "/" + kParamsFolder + "/" + name;
  for (const std::string& entry : folder_entries(folder.get(), folder_path)) {
    NamespaceObjectInfo info;
    info.kind = kParamsFolder;
    info.path = folder_path + "/" + entry;
    try {
      const FileDescriptor file =
          open_trusted_file(folder.get(), entry, info.path, O_RDONLY, 0, false);
      struct stat status {};
      if (::fstat(file.get(), &status) == 0) info.size = static_cast<std::size_t>(status.st_size);
      // Its owner holds the lock exclusively; a probe that gets it lets go at once.
      info.in_use = ::flock(file.get(), LOCK_SH | LOCK_NB) != 0;
    } catch (const Error&) {
      info.in_use = true;  // not ours to judge: left for a person
    }
    objects.push_back(std::move(info));
  }
  return objects;
}

std::size_t remove_param_stores(std::string_view namespace_name, bool force) {
  const std::string name = param_namespace(namespace_name);
  const FileDescriptor folder = open_param_folder(name, false);
  if (folder.get() < 0) return 0;
  const std::string folder_path = shm_root() + "/" + kParamsFolder + "/" + name;
  std::size_t removed = 0;
  for (const std::string& entry : folder_entries(folder.get(), folder_path)) {
    if (!force) {
      try {
        const FileDescriptor file =
            open_trusted_file(folder.get(), entry, folder_path + "/" + entry, O_RDONLY, 0, false);
        if (::flock(file.get(), LOCK_EX | LOCK_NB) != 0 || !still_linked(file.get())) continue;
        // Unlinked while locked: an owner that opened it meanwhile sees it gone and starts over.
        removed += ::unlinkat(folder.get(), entry.c_str(), 0) == 0 ? 1 : 0;
      } catch (const Error&) {
        continue;  // not ours to judge: left for a person
      }
    } else {
      removed += ::unlinkat(folder.get(), entry.c_str(), 0) == 0 ? 1 : 0;
    }
  }
  const FileDescriptor params = [&] {
    const std::string root = shm_root();
    const FileDescriptor root_folder =
        open_trusted_directory(AT_FDCWD, root, root, 0600, true, false, false);
    if (root_folder.get() < 0) return FileDescriptor();
    return open_trusted_directory(root_folder.get(), kParamsFolder, root + "/" + kParamsFolder,
                                  0600, false, false, false);
  }();
  if (params.get() >= 0) ::unlinkat(params.get(), name.c_str(), AT_REMOVEDIR);  // once empty
  return removed;
}

std::string read_param_bytes(const ParamSlot& slot) {
  if (const ParamRecord* record = slot.record.load(std::memory_order_acquire)) {
    return read_record_bytes(*record);
  }
  return slot.default_bytes;
}

}  // namespace detail

std::string param_service_name(std::string_view node) { return "_params." + std::string(node); }

std::vector<std::string> param_nodes(std::string_view namespace_name) {
  const std::string name = detail::param_namespace(namespace_name);
  const detail::FileDescriptor folder = detail::open_param_folder(name, false);
  std::vector<std::string> nodes;
  if (folder.get() < 0) return nodes;
  for (std::string& node : detail::folder_entries(
           folder.get(), detail::shm_root() + "/" + detail::kParamsFolder + "/" + name)) {
    try {
      detail::check_param_node_name(node);
      nodes.push_back(std::move(node));
    } catch (const ParamError&) {
      // A store being created, under a name no node can have.
    }
  }
  return nodes;
}

struct ParamStoreReader::State {
  std::string node;
  std::string namespace_name;
  std::string path;
  detail::ParamStoreView view;
};

ParamStoreReader::ParamStoreReader(std::string_view node, std::string_view namespace_name)
    : state_(std::make_unique<State>()) {
  State& state = *state_;
  state.node = std::string(node);
  state.namespace_name = detail::param_namespace(namespace_name);
  detail::check_param_node_name(node);
  state.path = detail::param_store_path(state.namespace_name, state.node);
  const detail::FileDescriptor folder = detail::open_param_folder(state.namespace_name, false);
  const auto missing = [&] {
    return ParamError(detail::node_and_namespace(node, state.namespace_name) +
                      " has no parameter store (it never ran with parameters here)");
  };
  if (folder.get() < 0) throw missing();
  detail::FileDescriptor file;
  try {
    file = detail::open_trusted_file(folder.get(), state.node, state.path, O_RDONLY, 0, false);
  } catch (const Error&) {
    if (::faccessat(folder.get(), state.node.c_str(), F_OK, AT_SYMLINK_NOFOLLOW) != 0) {
      throw missing();
    }
    throw;
  }
  struct stat status {};
  if (::fstat(file.get(), &status) != 0) {
    throw Error("cannot stat " + state.path + ": " + detail::errno_text(errno));
  }
  const auto size = static_cast<std::size_t>(status.st_size);
  if (size == 0) {
    // The owner's lock file, before its first store takes the name: no store yet.
    throw ParamError(detail::node_and_namespace(node, state.namespace_name) +
                     " has no parameter store yet (its node is starting)");
  }
  if (size < sizeof(detail::ParamStoreHeader)) {
    throw Error("parameter store " + state.path + " is not valid: it is shorter than its header");
  }
  void* address = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, file.get(), 0);
  if (address == MAP_FAILED) {
    throw Error("cannot map " + state.path + ": " + detail::errno_text(errno));
  }
  state.view =
      detail::view_param_store(std::make_shared<detail::ParamMapping>(address, size), state.path);
}

ParamStoreReader::~ParamStoreReader() = default;
ParamStoreReader::ParamStoreReader(ParamStoreReader&&) noexcept = default;
ParamStoreReader& ParamStoreReader::operator=(ParamStoreReader&&) noexcept = default;

const std::string& ParamStoreReader::node() const noexcept { return state_->node; }

const TypeDescription& ParamStoreReader::description() const noexcept {
  return state_->view.description;
}

std::vector<ParamInfo> ParamStoreReader::list() const {
  std::vector<ParamInfo> params;
  const detail::ParamStoreView& view = state_->view;
  for (std::size_t i = 0; i < view.declarations.size(); ++i) {
    const detail::ParamRecord& record = view.mapping->record(i);
    ParamInfo info;
    info.node = state_->node;
    info.declaration = view.declarations[i];
    // The version first: a value read after it is at least as new.
    info.version = record.version.load(std::memory_order_acquire);
    info.value = detail::read_param_value(info.declaration, record);
    params.push_back(std::move(info));
  }
  return params;
}

ParamInfo ParamStoreReader::get(std::string_view name) const {
  const detail::ParamStoreView& view = state_->view;
  for (std::size_t i = 0; i < view.declarations.size(); ++i) {
    if (view.declarations[i].name != name) continue;
    const detail::ParamRecord& record = view.mapping->record(i);
    ParamInfo info;
    info.node = state_->node;
    info.declaration = view.declarations[i];
    info.version = record.version.load(std::memory_order_acquire);
    info.value = detail::read_param_value(info.declaration, record);
    return info;
  }
  throw ParamError("node '" + state_->node + "' has no parameter '" + std::string(name) + "' (" +
                   detail::closest_names(name, view.declarations) + ")");
}

std::shared_ptr<const detail::ParamSlot> ParamStoreReader::record_slot(
    std::string_view name, const TypeRef& cpp_type) const {
  const detail::ParamStoreView& view = state_->view;
  for (std::size_t i = 0; i < view.declarations.size(); ++i) {
    if (view.declarations[i].name != name) continue;
    detail::check_param_cpp_type(view.declarations[i], cpp_type, cpp_type.name);
    auto slot = std::make_shared<detail::ParamSlot>();
    slot->declaration = view.declarations[i];
    const detail::ParamRecord& record = view.mapping->record(i);
    slot->mapping = view.mapping;
    slot->version.store(&record.version, std::memory_order_release);
    slot->word.store(&record.word, std::memory_order_release);
    slot->record.store(&record, std::memory_order_release);
    return slot;
  }
  throw ParamError("node '" + state_->node + "' has no parameter '" + std::string(name) + "' (" +
                   detail::closest_names(name, view.declarations) + ")");
}

bool ParamStoreReader::owner_alive() const noexcept {
  const std::uint64_t owner = state_->view.mapping->header().owner.load(std::memory_order_acquire);
  return owner != 0 && detail::identity_alive(owner);
}

std::uint32_t ParamStoreReader::owner_pid() const noexcept {
  return owner_alive() ? detail::identity_pid(
                             state_->view.mapping->header().owner.load(std::memory_order_acquire))
                       : 0;
}

std::uint64_t ParamStoreReader::change_count() const noexcept {
  return state_->view.mapping->header().change_count.load(std::memory_order_acquire);
}

std::uint64_t ParamStoreReader::wait_for_change(std::uint64_t seen,
                                                std::chrono::nanoseconds timeout) const {
  detail::ParamStoreHeader& header = state_->view.mapping->header();
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const std::uint32_t word = header.change_word.load(std::memory_order_acquire);
    const std::uint64_t count = header.change_count.load(std::memory_order_acquire);
    if (count != seen) return count;
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds::zero()) return count;
    detail::futex_wait(header.change_word, word,
                       std::chrono::duration_cast<std::chrono::nanoseconds>(left));
  }
}

namespace {

/// Keeps `value` for the node's next start, if no owner runs (the flock decides); none when
/// one started meanwhile.
std::optional<ParamSetResult> persist_for_next_start(const std::string& node,
                                                     const std::string& namespace_name,
                                                     std::string_view name,
                                                     std::string_view value) {
  const std::string path = detail::param_store_path(namespace_name, node);
  const detail::FileDescriptor folder = detail::open_param_folder(namespace_name, false);
  if (folder.get() < 0) return std::nullopt;
  const detail::FileDescriptor file =
      detail::open_trusted_file(folder.get(), node, path, O_RDWR, 0, false);
  if (::flock(file.get(), LOCK_EX | LOCK_NB) != 0) return std::nullopt;
  struct stat status {};
  if (::fstat(file.get(), &status) != 0) {
    throw Error("cannot stat " + path + ": " + detail::errno_text(errno));
  }
  const auto size = static_cast<std::size_t>(status.st_size);
  if (size < sizeof(detail::ParamStoreHeader)) {
    throw Error("parameter store " + path + " is not valid: it is shorter than its header");
  }
  void* address = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, file.get(), 0);
  if (address == MAP_FAILED) throw Error("cannot map " + path + ": " + detail::errno_text(errno));
  const detail::ParamStoreView view =
      detail::view_param_store(std::make_shared<detail::ParamMapping>(address, size), path);
  for (std::size_t i = 0; i < view.declarations.size(); ++i) {
    if (view.declarations[i].name != name) continue;
    detail::ParamRecord& record = view.mapping->record(i);
    detail::persist_param_value(record, value);
    return ParamSetResult{true, {}, record.version.load(std::memory_order_acquire)};
  }
  return std::nullopt;
}

/// A writer's way to one node's owner: its store and a client of its write service. Opening them
/// costs about 25 writes (a service client claims a reply topic, which means looking at every
/// process of the namespace), so set_param() keeps them between writes, per thread (a client
/// serves one caller at a time), and opens them again whenever they may be out of date.
struct ParamWriter {
  ParamWriter(const std::string& node, const std::string& namespace_name)
      : reader(node, namespace_name) {}
  ParamStoreReader reader;
  std::optional<RawServiceClient> client;
};

/// The kept writer of `node` (`reopen`: a new one); `opened` tells whether it is new.
ParamWriter& param_writer(const std::string& namespace_name, const std::string& node, bool reopen,
                          bool& opened) {
  thread_local std::map<std::string, std::unique_ptr<ParamWriter>> writers;
  std::unique_ptr<ParamWriter>& writer = writers[namespace_name + '/' + node];
  opened = !writer || reopen;
  if (opened) {
    writer.reset();  // a failed open leaves the entry empty, to be opened again
    writer = std::make_unique<ParamWriter>(node, namespace_name);
  }
  return *writer;
}

}  // namespace

ParamSetResult set_param(std::string_view node, std::string_view name, std::string_view value,
                         const ParamSetOptions& options) {
  const std::string namespace_name = detail::param_namespace(options.namespace_name);
  const std::string node_name(node);
  bool fresh = false;
  ParamWriter* writer = &param_writer(namespace_name, node_name, false, fresh);
  const auto reopen = [&] { writer = &param_writer(namespace_name, node_name, true, fresh); };
  ParamInfo current;
  std::string problem;
  for (;;) {
    // A kept store may be an older one than the node's now (a restart with other declarations
    // makes a new file): an unknown name or a refused value is judged again on a fresh one.
    try {
      current = writer->reader.get(name);
    } catch (const ParamError&) {
      if (fresh) throw;
      reopen();
      continue;
    }
    problem = detail::param_value_problem(current.declaration, value);
    if (problem.empty() || fresh) break;
    reopen();
  }
  const ParamDeclaration& declaration = current.declaration;
  const auto refused = [&](std::string reason) {
    return ParamSetResult{false, std::move(reason), current.version};
  };
  if (!problem.empty()) return refused("parameter '" + declaration.name + "': " + problem);
  const std::string canonical = detail::canonical_param_value(declaration, value);
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (!writer->client) {
      TopicOptions topic_options;
      topic_options.namespace_name = namespace_name;
      writer->client.emplace(detail::param_service_type(node_name), topic_options);
    }
    // A live server of the write service is the quick sign that the owner runs. Only without
    // one is the store asked (a read of /proc, which costs as much as a write), afresh.
    if (attempt > 0 || !writer->client->wait_for_server(std::chrono::nanoseconds::zero())) {
      if (!fresh) {
        reopen();
        --attempt;  // the same attempt again, with a store and a client just opened
        continue;
      }
      if (!writer->reader.owner_alive()) {
        if (!options.persist) return refused("node " + node_name + " is not running");
        if (auto kept = persist_for_next_start(node_name, namespace_name, name, canonical)) {
          return *kept;
        }
        continue;  // it started meanwhile: ask it
      }
    }
    if (declaration.read_only) {
      // A dump loaded back carries the read-only values as they are: writing what is already
      // there changes nothing, so it is no refusal.
      const ParamInfo current = writer->reader.get(name);
      if (detail::canonical_param_value(declaration, current.value) == canonical) {
        return ParamSetResult{true, {}, current.version};
      }
      return refused("parameter '" + declaration.name + "' is read-only while node " + node_name +
                     " runs");
    }
    RawServiceClient& client = *writer->client;
    const ParamStoreReader& reader = writer->reader;
    if (!client.wait_for_server(
            std::min<std::chrono::nanoseconds>(options.timeout, std::chrono::seconds(1)))) {
      if (!reader.owner_alive()) continue;
      return refused("node " + node_name + " does not answer parameter writes");
    }
    const std::string source = options.source.empty() ? detail::program_name() : options.source;
    const std::vector<std::byte> request = detail::encode_param_request(
        {std::string(name), canonical, source,
         std::chrono::duration_cast<std::chrono::nanoseconds>(options.timeout).count()});
    ServiceResult<std::vector<std::byte>> response =
        client.call(request, options.timeout + std::chrono::milliseconds(200));
    if (!response.has_value()) {
      if (!reader.owner_alive()) continue;
      return refused("node " + node_name + ": " + response.error().to_string());
    }
    return detail::decode_param_response(response.value());
  }
  return refused("node " + node_name + " is not running");
}

}  // namespace horus
