// Opening tensor pools: the pool files under <root>/@pool/<namespace>/, their validation, and the
// one mapping per pool that a process shares between its handles.
#include "horus/tensor_pool.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <mutex>
#include <random>
#include <vector>

#include "horus/detail/pool_mapping.hpp"
#include "horus/detail/shm_access.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"
#include "pool_layout.hpp"

namespace horus {

namespace detail {

namespace {

constexpr const char* kPoolFolder = "@pool";

std::uint64_t round_up(std::uint64_t value, std::uint64_t multiple) {
  return (value + multiple - 1) / multiple * multiple;
}

std::string namespace_of(std::string_view namespace_name) {
  std::string name = namespace_name.empty() ? current_namespace() : std::string(namespace_name);
  validate_segment_name("namespace", name);
  return name;
}

/// The checked folder <root>/@pool/<namespace> (-1 when missing and not `create`d).
FileDescriptor open_pool_folder(const std::string& namespace_name, unsigned mode, bool create,
                                std::string& path) {
  const std::string root = shm_root();
  const bool sharing = group_sharing(mode);
  const FileDescriptor root_folder =
      open_trusted_directory(AT_FDCWD, root, root, mode, true, sharing, create);
  if (root_folder.get() < 0) return FileDescriptor();
  const std::string pools = root + "/" + kPoolFolder;
  const FileDescriptor pool_folder =
      open_trusted_directory(root_folder.get(), kPoolFolder, pools, mode, false, sharing, create);
  if (pool_folder.get() < 0) return FileDescriptor();
  path = pools + "/" + namespace_name;
  return open_trusted_directory(pool_folder.get(), namespace_name, path, mode, false, sharing,
                                create);
}

PoolGeometry geometry_for(std::uint64_t block_size, std::uint64_t block_count) {
  PoolGeometry geometry;
  geometry.block_size = block_size;
  geometry.block_count = block_count;
  geometry.processes_offset = kPoolHeaderSize;
  geometry.states_offset = geometry.processes_offset + kMaxPoolProcesses * sizeof(PoolProcess);
  geometry.row_stride = round_up(block_count * sizeof(PoolHold), 64);
  geometry.holds_offset = geometry.states_offset + block_count * sizeof(BlockState);
  geometry.data_offset =
      round_up(geometry.holds_offset + kMaxPoolProcesses * geometry.row_stride, kPoolPage);
  geometry.total_size = geometry.data_offset + block_size * block_count;
  return geometry;
}

std::string validate_header(const PoolHeader& header, std::uint64_t file_size,
                            PoolGeometry& geometry) {
  if (header.magic != kPoolMagic) return "not a tensor pool (bad magic)";
  if (header.version != kPoolVersion) {
    return "pool version " + std::to_string(header.version) + ", this runtime reads " +
           std::to_string(kPoolVersion);
  }
  if (header.block_size == 0 || header.block_size % kPoolPage != 0 ||
      header.block_size > kMaxPoolBlockSize || header.block_count == 0 ||
      header.block_count > kMaxPoolBlocks || header.max_processes != kMaxPoolProcesses) {
    return "corrupt geometry";
  }
  geometry = geometry_for(header.block_size, header.block_count);
  if (header.processes_offset != geometry.processes_offset ||
      header.states_offset != geometry.states_offset ||
      header.holds_offset != geometry.holds_offset || header.row_stride != geometry.row_stride ||
      header.data_offset != geometry.data_offset || header.total_size != geometry.total_size) {
    return "corrupt geometry";
  }
  if (file_size < geometry.total_size) {
    return "truncated (" + std::to_string(file_size) + " bytes, the layout needs " +
           std::to_string(geometry.total_size) + ")";
  }
  return {};
}

std::uint64_t random_id() {
  std::uint64_t id = 0;
  while (id == 0) {
    if (::getrandom(&id, sizeof id, 0) != static_cast<ssize_t>(sizeof id)) {
      std::random_device device;
      id = (std::uint64_t{device()} << 32) ^ device();
    }
  }
  return id;
}

// Liveness and set-up are two byte-range locks of the pool file (open file description locks:
// the kernel drops them with the last descriptor, so also when a process dies). kSetupByte is
// held exclusively while one opener validates or lays out the file; kUsersByte is held shared by
// every process that maps the pool, for the mapping's life. clean_pools removes a file only when
// it can take both exclusively: then nobody maps it and nobody is opening it.
constexpr off_t kSetupByte = 0;
constexpr off_t kUsersByte = 1;

/// Sets the lock `type` (F_RDLCK, F_WRLCK, F_UNLCK) on `byte`, waiting for it when `wait`.
/// Returns false when it is held elsewhere and not `wait`. Throws horus::Error.
bool lock_pool_byte(int file, short type, off_t byte, bool wait, const std::string& path) {
  struct flock lock {};
  lock.l_type = type;
  lock.l_whence = SEEK_SET;
  lock.l_start = byte;
  lock.l_len = 1;
  while (::fcntl(file, wait ? F_OFD_SETLKW : F_OFD_SETLK, &lock) != 0) {
    if (errno == EINTR) continue;
    if (!wait && (errno == EAGAIN || errno == EACCES)) return false;
    throw Error("cannot lock tensor pool " + path + ": " + errno_text(errno));
  }
  return true;
}

/// The names in the pool folder `folder` (without "." and "..").
std::vector<std::string> pool_file_names(int folder) {
  std::vector<std::string> names;
  const int duplicate = ::fcntl(folder, F_DUPFD_CLOEXEC, 0);
  if (DIR* dir = duplicate >= 0 ? ::fdopendir(duplicate) : nullptr) {
    // This DIR stream is local to the call, which is all readdir needs to be safe.
    while (const dirent* entry = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe)
      const std::string name = entry->d_name;
      if (name != "." && name != "..") names.push_back(name);
    }
    ::closedir(dir);
  } else if (duplicate >= 0) {
    ::close(duplicate);
  }
  return names;
}

struct Registry {
  std::mutex mutex;
  /// By path: one mapping per pool per process.
  std::map<std::string, std::weak_ptr<PoolMapping>> pools;
};

Registry& registry() {
  static Registry instance;
  return instance;
}

/// Opens (creating when `create`) the pool file `name` of the namespace; the registry's lock is
/// held by the caller. Returns nullptr when it does not exist and not `create`.
std::shared_ptr<PoolMapping> open_mapping(Registry& pools, const std::string& namespace_name,
                                          const std::string& name, const TensorPoolOptions& options,
                                          bool create) {
  std::string folder_path;
  const FileDescriptor folder = open_pool_folder(namespace_name, options.mode, create, folder_path);
  if (folder.get() < 0) return nullptr;
  const std::string path = folder_path + "/" + name;
  if (auto found = pools.pools.find(path); found != pools.pools.end()) {
    if (std::shared_ptr<PoolMapping> open = found->second.lock()) {
      open->set_policy(options.on_exhaustion);
      return open;
    }
  }
  for (int attempt = 0; attempt < 16; ++attempt) {
    struct stat existing {};
    if (!create && ::fstatat(folder.get(), name.c_str(), &existing, AT_SYMLINK_NOFOLLOW) != 0) {
      return nullptr;
    }
    FileDescriptor file =
        open_trusted_file(folder.get(), name, path, O_RDWR | (create ? O_CREAT : 0), options.mode,
                          group_sharing(options.mode));
    lock_pool_byte(file.get(), F_WRLCK, kSetupByte, true, path);
    struct stat opened {};
    struct stat current {};
    if (::fstat(file.get(), &opened) != 0 ||
        ::fstatat(folder.get(), name.c_str(), &current, AT_SYMLINK_NOFOLLOW) != 0 ||
        opened.st_dev != current.st_dev || opened.st_ino != current.st_ino) {
      continue;  // removed between open and lock: open the live file
    }
    auto mapping = std::make_shared<PoolMapping>(std::move(file), path, name, options);
    lock_pool_byte(mapping->file(), F_RDLCK, kUsersByte, true, path);
    lock_pool_byte(mapping->file(), F_UNLCK, kSetupByte, true, path);
    pools.pools[path] = mapping;
    return mapping;
  }
  throw Error("tensor pool " + path + " keeps being removed while opening it");
}

}  // namespace

MappedPool map_pool_file(int file, const std::string& path, const TensorPoolOptions& options) {
  struct stat info {};
  if (::fstat(file, &info) != 0) {
    throw Error("cannot stat tensor pool " + path + ": " + errno_text(errno));
  }
  const auto file_size = static_cast<std::uint64_t>(info.st_size);
  PoolGeometry geometry;
  bool fresh = file_size < kPoolHeaderSize;
  if (!fresh) {
    PoolHeader header{};
    if (::pread(file, &header, sizeof header, 0) != static_cast<ssize_t>(sizeof header)) {
      throw Error("cannot read tensor pool " + path + ": " + errno_text(errno));
    }
    // A creator that died before finishing left no ready mark: lay the file out again.
    fresh = header.magic == kPoolMagic && header.ready.load(std::memory_order_relaxed) == 0;
    if (!fresh) {
      if (std::string reason = validate_header(header, file_size, geometry); !reason.empty()) {
        throw Error("refusing tensor pool " + path + ": " + reason +
                    " (remove the file once no process uses it)");
      }
    }
  }
  if (fresh) {
    check_creation_mode(options.mode, "tensor pool " + path);
    if (options.block_size == 0 || options.block_size > kMaxPoolBlockSize) {
      throw Error("tensor pool " + path + ": block_size must be 1 byte to 1 GiB, not " +
                  std::to_string(options.block_size));
    }
    if (options.block_count == 0 || options.block_count > kMaxPoolBlocks) {
      throw Error("tensor pool " + path + ": block_count must be 1 to " +
                  std::to_string(kMaxPoolBlocks) + ", not " + std::to_string(options.block_count));
    }
    geometry = geometry_for(round_up(options.block_size, kPoolPage), options.block_count);
    if (geometry.total_size > kMaxPoolSize) {
      throw Error("tensor pool " + path + ": " + std::to_string(geometry.total_size) +
                  " bytes is more than the 64 GiB a pool may have");
    }
    // The blocks are not allocated up front (pages come as they are written), so a /dev/shm
    // too small for the whole pool is refused here rather than as SIGBUS on a later write.
    struct statvfs space {};
    if (::fstatvfs(file, &space) == 0 &&
        static_cast<std::uint64_t>(space.f_bavail) * space.f_frsize < geometry.total_size) {
      throw Error("tensor pool " + path + " needs " + std::to_string(geometry.total_size) +
                  " bytes, /dev/shm has " +
                  std::to_string(static_cast<std::uint64_t>(space.f_bavail) * space.f_frsize) +
                  " free (fewer or smaller blocks?)");
    }
    ::fchmod(file, static_cast<mode_t>(options.mode));
    if (::ftruncate(file, 0) != 0 ||
        ::ftruncate(file, static_cast<off_t>(geometry.total_size)) != 0) {
      throw Error("cannot size tensor pool " + path + ": " + errno_text(errno));
    }
    // The tables are allocated now: a full /dev/shm fails here, with a message.
    if (const int error = ::posix_fallocate(file, 0, static_cast<off_t>(geometry.data_offset));
        error != 0) {
      ::ftruncate(file, 0);
      throw Error("cannot allocate tensor pool " + path + ": " + errno_text(error));
    }
  }
  void* base = ::mmap(nullptr, geometry.total_size, PROT_READ | PROT_WRITE, MAP_SHARED, file, 0);
  if (base == MAP_FAILED) {
    throw Error("cannot map tensor pool " + path + ": " + errno_text(errno));
  }
  auto* header = static_cast<PoolHeader*>(base);
  if (fresh) {
    header->version = kPoolVersion;
    header->header_size = kPoolHeaderSize;
    header->pool_id = random_id();
    header->block_size = geometry.block_size;
    header->block_count = geometry.block_count;
    header->max_processes = kMaxPoolProcesses;
    header->processes_offset = geometry.processes_offset;
    header->states_offset = geometry.states_offset;
    header->holds_offset = geometry.holds_offset;
    header->row_stride = geometry.row_stride;
    header->data_offset = geometry.data_offset;
    header->total_size = geometry.total_size;
    header->magic = kPoolMagic;
    header->ready.store(1, std::memory_order_release);
  }
  return MappedPool{base, static_cast<std::size_t>(geometry.total_size), geometry};
}

std::shared_ptr<PoolMapping> find_pool(std::uint64_t id, const std::string& namespace_name) {
  const std::string space = namespace_of(namespace_name);
  Registry& pools = registry();
  const std::lock_guard<std::mutex> guard(pools.mutex);
  std::string folder_path;
  const FileDescriptor folder = open_pool_folder(space, 0600, false, folder_path);
  if (folder.get() < 0) return nullptr;
  const std::string prefix = folder_path + "/";
  for (auto& [path, weak] : pools.pools) {
    if (path.rfind(prefix, 0) == 0) {
      if (std::shared_ptr<PoolMapping> open = weak.lock(); open && open->id() == id) {
        return open;
      }
    }
  }
  const std::vector<std::string> names = pool_file_names(folder.get());
  TensorPoolOptions options;
  options.namespace_name = space;
  for (const std::string& name : names) {
    try {
      std::shared_ptr<PoolMapping> mapping = open_mapping(pools, space, name, options, false);
      if (mapping && mapping->id() == id) return mapping;
    } catch (const Error&) {
      // A pool this process may not or cannot open is not the one named.
    }
  }
  return nullptr;
}

}  // namespace detail

TensorPool TensorPool::open(std::string_view name, const TensorPoolOptions& options) {
  detail::validate_segment_name("tensor pool", name);
  const std::string space = detail::namespace_of(options.namespace_name);
  detail::Registry& pools = detail::registry();
  const std::lock_guard<std::mutex> guard(pools.mutex);
  return TensorPool(detail::open_mapping(pools, space, std::string(name), options, true));
}

const std::string& TensorPool::name() const noexcept { return mapping_->name(); }
std::uint64_t TensorPool::id() const noexcept { return mapping_->id(); }
std::size_t TensorPool::block_size() const noexcept { return mapping_->block_size(); }
std::size_t TensorPool::block_count() const noexcept { return mapping_->block_count(); }
PoolExhaustion TensorPool::on_exhaustion() const noexcept { return mapping_->policy(); }
void TensorPool::set_on_exhaustion(PoolExhaustion policy) noexcept { mapping_->set_policy(policy); }
TensorPoolStats TensorPool::stats() const noexcept { return mapping_->stats(); }
std::uint64_t TensorPool::references(const msg::PoolBlock& block) const noexcept {
  return mapping_->references(block);
}
bool TensorPool::contains(const void* address) const noexcept {
  return mapping_->contains(address);
}
std::size_t TensorPool::reclaim() noexcept {
  mapping_->reclaim_dead();
  return mapping_->sweep_unheld();
}

TensorPool default_pool() {
  // Kept open for the life of the process, one per namespace it used: the pool a camera loop
  // allocates from every frame must not be re-opened (a syscall) each time.
  static std::mutex mutex;
  static std::map<std::string, TensorPool> opened;
  const std::string space = detail::namespace_of({});
  const std::lock_guard<std::mutex> guard(mutex);
  if (auto found = opened.find(space); found != opened.end()) {
    return found->second;
  }
  TensorPool pool = TensorPool::open("default");
  opened.emplace(space, pool);
  return pool;
}

void remove_pools(std::string_view namespace_name) {
  const std::string space = detail::namespace_of(namespace_name);
  std::string folder_path;
  const detail::FileDescriptor folder = detail::open_pool_folder(space, 0600, false, folder_path);
  if (folder.get() < 0) return;
  for (const std::string& name : detail::pool_file_names(folder.get())) {
    ::unlinkat(folder.get(), name.c_str(), 0);
  }
  ::rmdir(folder_path.c_str());
}

std::size_t clean_pools(std::string_view namespace_name) {
  const std::string space = detail::namespace_of(namespace_name);
  std::string folder_path;
  const detail::FileDescriptor folder = detail::open_pool_folder(space, 0600, false, folder_path);
  if (folder.get() < 0) return 0;
  std::size_t removed = 0;
  for (const std::string& name : detail::pool_file_names(folder.get())) {
    const std::string path = folder_path + "/" + name;
    const detail::FileDescriptor file(
        ::openat(folder.get(), name.c_str(), O_RDWR | O_NOFOLLOW | O_CLOEXEC));
    if (file.get() < 0) continue;
    try {
      if (!detail::lock_pool_byte(file.get(), F_WRLCK, detail::kSetupByte, false, path) ||
          !detail::lock_pool_byte(file.get(), F_WRLCK, detail::kUsersByte, false, path)) {
        continue;  // in use, or being opened
      }
    } catch (const Error&) {
      continue;  // not lockable: not ours to judge
    }
    struct stat opened {};
    struct stat current {};
    if (::fstat(file.get(), &opened) == 0 &&
        ::fstatat(folder.get(), name.c_str(), &current, AT_SYMLINK_NOFOLLOW) == 0 &&
        opened.st_dev == current.st_dev && opened.st_ino == current.st_ino &&
        ::unlinkat(folder.get(), name.c_str(), 0) == 0) {
      ++removed;
    }
  }
  ::rmdir(folder_path.c_str());  // only once empty
  return removed;
}

}  // namespace horus
