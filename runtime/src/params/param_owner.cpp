// The owner of a node's parameter store: opening or taking over the file under its flock,
// starting values (defaults, the parameter file, persisted values), and the write service: it
// calls on_param_change() itself while the node's thread sleeps, and otherwise queues the change
// for that thread to deliver between two ticks.
#include "horus/internal/param_owner.hpp"

#include <fcntl.h>
#include <linux/futex.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "horus/detail/process.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/scheduler.hpp"
#include "param_internal.hpp"

namespace horus::detail {
namespace {

/// How long a start waits for a flock held only briefly (a persisting writer, a cleaner).
constexpr auto kLockPatience = std::chrono::milliseconds(500);
constexpr auto kDefaultWriteTimeout = std::chrono::seconds(5);

/// Maps the file through a description of its own: a mapping holds its open file description,
/// and with it a flock taken there, for as long as it lives (the node's handles keep theirs
/// after the owner lets go of the lock).
std::shared_ptr<ParamMapping> map_file(int fd, std::size_t size, const std::string& path) {
  const std::string self = "/proc/self/fd/" + std::to_string(fd);
  const FileDescriptor own(::open(self.c_str(), O_RDWR | O_CLOEXEC));
  if (own.get() < 0) throw Error("cannot reopen " + path + ": " + errno_text(errno));
  void* address = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, own.get(), 0);
  if (address == MAP_FAILED) throw Error("cannot map " + path + ": " + errno_text(errno));
  return std::make_shared<ParamMapping>(address, size);
}

std::size_t file_size(int fd, const std::string& path) {
  struct stat status {};
  if (::fstat(fd, &status) != 0) throw Error("cannot stat " + path + ": " + errno_text(errno));
  return static_cast<std::size_t>(status.st_size);
}

std::string owner_program(const ParamStoreHeader& header) {
  char text[sizeof header.owner_program + 1] = {};
  for (std::size_t i = 0; i < 4; ++i) {
    const std::uint64_t word = header.owner_program[i].load(std::memory_order_relaxed);
    std::memcpy(text + i * 8, &word, 8);
  }
  return text;
}

/// Who holds the store's lock, as the header tells it.
std::string holder_of(int fd, std::size_t size) {
  if (size < sizeof(ParamStoreHeader)) return "another process";
  void* address = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
  if (address == MAP_FAILED) return "another process";
  const ParamMapping mapping(address, size);
  const ParamStoreHeader& header = mapping.header();
  if (std::memcmp(header.magic, kParamStoreMagic, sizeof kParamStoreMagic) != 0) {
    return "another process";
  }
  const std::uint64_t owner = header.owner.load(std::memory_order_acquire);
  if (owner == 0) return "another process";
  const std::uint32_t pid = identity_pid(owner);
  std::string program = owner_program(header);
  if (program.empty()) program = process_name(pid);
  return "pid " + std::to_string(pid) + (program.empty() ? "" : " (" + program + ")");
}

}  // namespace

struct ParamOwner::State {
  Node* node = nullptr;
  std::string name;
  std::string namespace_name;
  std::string path;
  FileDescriptor file;  // holds the flock
  std::shared_ptr<ParamMapping> mapping;
  std::vector<ParamDeclaration> declarations;

  struct Change {
    std::size_t index = 0;
    std::string value;
    std::string source;
    bool taken = false;
    bool done = false;
    ParamSetResult result;
  };
  std::mutex mutex;
  std::condition_variable answered;
  std::deque<std::shared_ptr<Change>> queue;
  bool stopping = false;
  std::unique_ptr<RawServiceServer> server;
  std::thread thread;
  std::function<void()> wake;
  ParamOwner::AcceptedChange accepted;

  ParamRecord& record(std::size_t index) const { return mapping->record(index); }

  void lock_store(const FileDescriptor& folder);
  void build_store(const FileDescriptor& folder, const std::string& description,
                   std::map<std::string, std::string>& persisted);
  /// Why a write of `value` to `parameter` is refused before the node is asked (no such
  /// parameter, a value outside the declaration, read-only), or nullopt; `index`: the
  /// parameter's.
  std::optional<ParamSetResult> refusal(std::string_view parameter, std::string_view value,
                                        std::size_t& index) const;
  ParamSetResult handle(const ParamWriteRequest& request, ParamOwner& owner);
  /// Offers parameter `index`'s change to the node and stores it when accepted (node's thread).
  ParamSetResult offer(std::size_t index, const std::string& value, const std::string& source);
};

void ParamOwner::State::lock_store(const FileDescriptor& folder) {
  const auto give_up = std::chrono::steady_clock::now() + kLockPatience;
  for (;;) {
    FileDescriptor opened =
        open_trusted_file(folder.get(), name, path, O_RDWR | O_CREAT, 0600, false);
    if (::flock(opened.get(), LOCK_EX | LOCK_NB) != 0) {
      const std::string holder = holder_of(opened.get(), file_size(opened.get(), path));
      if (holder != "another process" || std::chrono::steady_clock::now() >= give_up) {
        throw ParamError("node '" + name + "' already runs in " + holder +
                         ": its parameter store " + path + " has one owner at a time");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      continue;
    }
    if (!still_linked(opened.get())) continue;  // replaced or cleaned before we locked it
    file = std::move(opened);
    return;
  }
}

void ParamOwner::State::build_store(const FileDescriptor& folder, const std::string& description,
                                    std::map<std::string, std::string>& persisted) {
  // What the previous owner left: values persisted for this start, and a layout to reuse.
  const std::size_t existing_size = file_size(file.get(), path);
  std::shared_ptr<ParamMapping> existing;
  bool reusable = false;
  if (existing_size >= sizeof(ParamStoreHeader)) {
    try {
      existing = map_file(file.get(), existing_size, path);
      const ParamStoreView view = view_param_store(existing, path);
      for (std::size_t i = 0; i < view.declarations.size(); ++i) {
        std::string value = persisted_param_value(existing->record(i));
        if (!value.empty()) persisted[view.declarations[i].name] = std::move(value);
      }
      reusable = view.description_bytes == description;
    } catch (const Error&) {
      existing.reset();  // a foreign or damaged file: replaced below
    }
  }
  if (reusable) {
    mapping = std::move(existing);
    for (std::size_t i = 0; i < declarations.size(); ++i) persist_param_value(record(i), {});
    return;
  }
  // A new file, complete before it takes the name (readers of the old one keep their mapping).
  const std::size_t description_offset = sizeof(ParamStoreHeader);
  const std::size_t records_offset =
      (description_offset + description.size() + alignof(ParamRecord) - 1) / alignof(ParamRecord) *
      alignof(ParamRecord);
  const std::size_t size = records_offset + declarations.size() * sizeof(ParamRecord);
  // "~" is no node name's character, so listings never show a store being made.
  const std::string temporary = "~" + name + "." + std::to_string(this_pid());
  ::unlinkat(folder.get(), temporary.c_str(), 0);
  FileDescriptor fresh = open_trusted_file(folder.get(), temporary, path + ".new",
                                           O_RDWR | O_CREAT | O_EXCL, 0600, false);
  if (::ftruncate(fresh.get(), static_cast<off_t>(size)) != 0 ||
      ::flock(fresh.get(), LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::unlinkat(folder.get(), temporary.c_str(), 0);
    throw Error("cannot create the parameter store " + path + ": " + errno_text(error));
  }
  mapping = map_file(fresh.get(), size, path);
  ParamStoreHeader& header = mapping->header();
  std::memcpy(header.magic, kParamStoreMagic, sizeof kParamStoreMagic);
  header.layout = kParamStoreLayout;
  header.record_count = static_cast<std::uint32_t>(declarations.size());
  header.description_offset = description_offset;
  header.description_size = description.size();
  header.records_offset = records_offset;
  header.file_size = size;
  std::memcpy(static_cast<char*>(mapping->address) + description_offset, description.data(),
              description.size());
  if (::renameat(folder.get(), temporary.c_str(), folder.get(), name.c_str()) != 0) {
    const int error = errno;
    ::unlinkat(folder.get(), temporary.c_str(), 0);
    throw Error("cannot create the parameter store " + path + ": " + errno_text(error));
  }
  file = std::move(fresh);  // the old file's lock goes with its descriptor
}

ParamOwner::ParamOwner(Node& node, std::string name,
                       const std::map<std::string, std::string>* file_values,
                       const std::map<std::string, std::string>* replay_values)
    : state_(std::make_unique<State>()) {
  State& state = *state_;
  state.node = &node;
  state.name = std::move(name);
  check_param_node_name(state.name);
  state.namespace_name = param_namespace({});
  state.path = param_store_path(state.namespace_name, state.name);
  state.declarations = node.param_declarations();
  const std::string description = describe_params(state.name, state.declarations);

  const FileDescriptor folder = open_param_folder(state.namespace_name, true);
  state.lock_store(folder);
  std::map<std::string, std::string> persisted;
  state.build_store(folder, description, persisted);

  // Starting values: defaults, the parameter file, then what was persisted for this start.
  std::vector<std::string> values;
  for (const ParamDeclaration& declaration : state.declarations) {
    values.push_back(declaration.default_value);
  }
  for (std::size_t i = 0; i < state.declarations.size(); ++i) {
    const ParamDeclaration& declaration = state.declarations[i];
    if (file_values != nullptr) {
      if (const auto found = file_values->find(declaration.name); found != file_values->end()) {
        values[i] = found->second;
      }
    }
    if (const auto found = persisted.find(declaration.name); found != persisted.end()) {
      // The declaration may have changed since the value was kept: only a fitting one counts.
      if (param_value_problem(declaration, found->second).empty()) values[i] = found->second;
    }
    if (replay_values != nullptr) {
      // A replay starts where the recorded node did, as far as the declaration still allows.
      if (const auto found = replay_values->find(declaration.name);
          found != replay_values->end() &&
          param_value_problem(declaration, found->second).empty()) {
        values[i] = found->second;
      }
    }
  }
  ParamStoreHeader& header = state.mapping->header();
  for (std::size_t i = 0; i < state.declarations.size(); ++i) {
    ParamRecord& record = state.record(i);
    write_param_value(state.declarations[i], record, values[i]);
    record.version.store(1, std::memory_order_release);
  }
  char program[sizeof header.owner_program] = {};
  const std::string own_program = program_name();
  own_program.copy(program, sizeof program - 1);  // the last byte stays NUL
  for (std::size_t i = 0; i < 4; ++i) {
    std::uint64_t word = 0;
    std::memcpy(&word, program + i * 8, 8);
    header.owner_program[i].store(word, std::memory_order_relaxed);
  }
  header.owner.store(this_process_identity(), std::memory_order_release);
  count_param_change(header);

  // The node's handles read the store from now on (the mapping lives as long as they do).
  for (std::size_t i = 0; i < node.param_slots_.size(); ++i) {
    ParamSlot& slot = *node.param_slots_[i];
    ParamRecord& record = state.record(i);
    slot.mapping = state.mapping;
    slot.version.store(&record.version, std::memory_order_release);
    slot.word.store(&record.word, std::memory_order_release);
    slot.record.store(&record, std::memory_order_release);
  }
}

ParamOwner::~ParamOwner() {
  State& state = *state_;
  {
    std::lock_guard lock(state.mutex);
    state.stopping = true;
    for (const auto& change : state.queue) {
      change->done = true;
      change->result = ParamSetResult{false, "node " + state.name + " stopped", 0};
    }
    state.queue.clear();
  }
  state.answered.notify_all();
  if (state.server) state.server->stop();
  if (state.thread.joinable()) state.thread.join();
  if (state.server) state.server->withdraw();
  ParamStoreHeader& header = state.mapping->header();
  header.owner.store(0, std::memory_order_release);
  count_param_change(header);
}

void ParamOwner::serve(std::function<void()> wake) {
  State& state = *state_;
  state.wake = std::move(wake);
  TopicOptions options;
  options.namespace_name = state.namespace_name;
  state.server = std::make_unique<RawServiceServer>(param_service_type(state.name), options);
  state.thread = std::thread([this] {
    State& serving = *state_;
    while (!serving.server->stopped()) {
      std::optional<RawServiceServer::Request> request =
          serving.server->next(std::chrono::milliseconds(250));
      if (!request) continue;
      ParamSetResult result;
      try {
        result = serving.handle(decode_param_request(request->payload), *this);
      } catch (const std::exception& e) {
        result = ParamSetResult{false, e.what(), 0};
      }
      serving.server->answer(request->caller, encode_param_response(result));
    }
  });
}

std::optional<ParamSetResult> ParamOwner::State::refusal(std::string_view parameter,
                                                         std::string_view value,
                                                         std::size_t& index) const {
  index = declarations.size();
  for (std::size_t i = 0; i < declarations.size(); ++i) {
    if (declarations[i].name == parameter) index = i;
  }
  if (index == declarations.size()) {
    return ParamSetResult{
        false, "node '" + name + "' has no parameter '" + std::string(parameter) + "'", 0};
  }
  const ParamDeclaration& declaration = declarations[index];
  const std::uint64_t version = record(index).version.load(std::memory_order_acquire);
  if (const std::string problem = param_value_problem(declaration, value); !problem.empty()) {
    return ParamSetResult{false, "parameter '" + declaration.name + "': " + problem, version};
  }
  if (declaration.read_only) {
    return ParamSetResult{
        false, "parameter '" + declaration.name + "' is read-only while node " + name + " runs",
        version};
  }
  return std::nullopt;
}

ParamSetResult ParamOwner::State::handle(const ParamWriteRequest& request, ParamOwner& owner) {
  std::size_t index = 0;
  if (std::optional<ParamSetResult> refused = refusal(request.name, request.value, index)) {
    return *refused;
  }
  const ParamDeclaration& declaration = declarations[index];
  // The node's thread sleeps: no hop to it (a wake and a wait), the node is called from here.
  if (owner.take_idle_node()) {
    ParamSetResult result =
        offer(index, canonical_param_value(declaration, request.value), request.source);
    owner.give_back();
    return result;
  }
  const std::uint64_t version = record(index).version.load(std::memory_order_acquire);
  auto change = std::make_shared<Change>();
  change->index = index;
  change->value = canonical_param_value(declaration, request.value);
  change->source = request.source;
  std::unique_lock lock(mutex);
  if (stopping) return ParamSetResult{false, "node " + name + " stopped", version};
  queue.push_back(change);
  owner.pending_.store(true, std::memory_order_seq_cst);
  lock.unlock();
  if (wake) wake();
  // The node's thread may have lent the node between the first look and the flag: one side or
  // the other delivers (idle() stores, then loads the flag; this stored it, now loads the state).
  if (owner.take_idle_node()) {
    owner.deliver();
    owner.give_back();
  }
  lock.lock();
  const auto timeout = request.timeout_ns > 0 ? std::chrono::nanoseconds(request.timeout_ns)
                                              : std::chrono::nanoseconds(kDefaultWriteTimeout);
  const bool done = answered.wait_for(lock, timeout, [&] { return change->done || stopping; });
  if (!done || !change->done) {
    if (!change->taken) {
      std::erase(queue, change);
      return ParamSetResult{
          false, "node " + name + " did not take the change in time (it does not tick)", version};
    }
    answered.wait(lock, [&] { return change->done; });
  }
  return change->result;
}

bool ParamOwner::take_idle_node() noexcept {
  std::uint32_t expected = kIdle;
  return holder_.compare_exchange_strong(expected, kHeldByService, std::memory_order_seq_cst);
}

void ParamOwner::give_back() noexcept {
  if (holder_.exchange(kIdle, std::memory_order_seq_cst) & kNodeWaits) {
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&holder_), FUTEX_WAKE | FUTEX_PRIVATE_FLAG,
            1, nullptr, nullptr, 0);
  }
}

void ParamOwner::idle() noexcept {
  if (pending()) deliver();
  holder_.store(kIdle, std::memory_order_seq_cst);
  deliver_while_idle();
}

void ParamOwner::deliver_while_idle() noexcept {
  if (!pending_.load(std::memory_order_seq_cst)) return;
  hold();
  deliver();
  holder_.store(kIdle, std::memory_order_seq_cst);
}

void ParamOwner::hold() noexcept {
  for (;;) {
    std::uint32_t seen = kIdle;
    if (holder_.compare_exchange_strong(seen, kHeldByNode, std::memory_order_seq_cst)) return;
    if (seen == kHeldByNode) return;  // never lent
    // The service thread is in on_param_change(): wait for its give_back().
    if (seen == kHeldByService &&
        !holder_.compare_exchange_strong(seen, kHeldByService | kNodeWaits,
                                         std::memory_order_seq_cst)) {
      continue;
    }
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&holder_), FUTEX_WAIT | FUTEX_PRIVATE_FLAG,
            kHeldByService | kNodeWaits, nullptr, nullptr, 0);
  }
}

void ParamOwner::deliver() noexcept {
  State& state = *state_;
  pending_.store(false, std::memory_order_relaxed);
  std::deque<std::shared_ptr<State::Change>> changes;
  {
    std::lock_guard lock(state.mutex);
    changes.swap(state.queue);
    for (const auto& change : changes) change->taken = true;
  }
  for (const auto& change : changes) {
    ParamSetResult result = state.offer(change->index, change->value, change->source);
    std::lock_guard lock(state.mutex);
    change->result = std::move(result);
    change->done = true;
  }
  state.answered.notify_all();
}

ParamSetResult ParamOwner::State::offer(std::size_t index, const std::string& value,
                                        const std::string& source) {
  const ParamDeclaration& declaration = declarations[index];
  ParamRecord& target = record(index);
  const std::uint64_t version = target.version.load(std::memory_order_relaxed);
  ParamSetResult result{false, {}, version};
  try {
    ParamChange offered;
    offered.declaration = &declaration;
    offered.value = value;
    offered.source = source;
    const ParamVerdict verdict = node->on_param_change(offered);
    if (verdict.accepted()) {
      write_param_value(declaration, target, value);
      target.version.store(version + 1, std::memory_order_release);
      count_param_change(mapping->header());
      result = ParamSetResult{true, {}, version + 1};
    } else {
      result.reason = "node " + name + " refused: " + verdict.reason();
    }
  } catch (const std::exception& e) {
    result.reason = "node " + name + ": on_param_change threw: " + e.what();
  } catch (...) {
    result.reason = "node " + name + ": on_param_change threw";
  }
  if (result.accepted && accepted) {
    try {
      accepted(declaration, value, result.version, source);
    } catch (...) {
      // The change stands; only telling of it failed (the listener reports its own errors).
    }
  }
  return result;
}

ParamSetResult ParamOwner::apply(std::string_view name, const std::string& value,
                                 const std::string& source) noexcept {
  State& state = *state_;
  try {
    std::size_t index = 0;
    if (std::optional<ParamSetResult> refused = state.refusal(name, value, index)) {
      return *refused;
    }
    return state.offer(index, canonical_param_value(state.declarations[index], value), source);
  } catch (const std::exception& e) {
    return ParamSetResult{false, e.what(), 0};
  }
}

void ParamOwner::on_accepted(AcceptedChange listener) { state_->accepted = std::move(listener); }

}  // namespace horus::detail
