// What the kernel says about memory, machine-wide and per process, for horus_soak's "nothing left,
// nothing growing" checks. Linux /proc and statvfs only; every reader returns -1 (or an empty
// text) for a figure it cannot read, so a process that just died is a missing sample, not an error.
#pragma once

#include <dirent.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/types.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace soak {

/// The value of `key` (e.g. "Shmem:") in a "Key:   123 kB"-style file, in the file's unit.
inline std::int64_t proc_field(const std::string& path, std::string_view key) {
  std::ifstream file(path);
  std::string line;
  while (std::getline(file, line)) {
    if (line.starts_with(key)) {
      std::istringstream value(line.substr(key.size()));
      std::int64_t number = -1;
      value >> number;
      return number;
    }
  }
  return -1;
}

/// Machine-wide figures: /proc/meminfo (kB) and the tmpfs that holds /dev/shm.
struct MachineMemory {
  std::int64_t shmem_kb = -1;          // every shared-memory page: tmpfs files, memfds, MAP_SHARED
  std::int64_t mem_available_kb = -1;  // what the kernel could give without swapping
  std::int64_t dev_shm_used_kb = -1;   // blocks in use on /dev/shm, all users
  std::int64_t dev_shm_entries = -1;   // inodes in use on /dev/shm (files and folders)
};

inline MachineMemory machine_memory() {
  MachineMemory memory;
  memory.shmem_kb = proc_field("/proc/meminfo", "Shmem:");
  memory.mem_available_kb = proc_field("/proc/meminfo", "MemAvailable:");
  struct statvfs shm {};
  if (::statvfs("/dev/shm", &shm) == 0) {
    memory.dev_shm_used_kb =
        static_cast<std::int64_t>((shm.f_blocks - shm.f_bfree) * shm.f_frsize / 1024);
    memory.dev_shm_entries = static_cast<std::int64_t>(shm.f_files - shm.f_ffree);
  }
  return memory;
}

/// Blocks (kB) the files and folders under `root` hold on their file system, leaving out those
/// under the paths in `excluded`. Entries that vanish during the walk are skipped (other programs
/// create and remove theirs meanwhile).
inline std::int64_t tree_kb(const std::string& root, const std::vector<std::string>& excluded) {
  namespace fs = std::filesystem;
  const auto left_out = [&excluded](const std::string& path) {
    return std::any_of(excluded.begin(), excluded.end(), [&path](const std::string& prefix) {
      return path == prefix || path.starts_with(prefix + "/");
    });
  };
  std::int64_t kb = 0;
  std::error_code error;
  fs::recursive_directory_iterator entry(root, fs::directory_options::skip_permission_denied,
                                         error);
  for (; !error && entry != fs::recursive_directory_iterator(); entry.increment(error)) {
    const std::string path = entry->path().string();
    if (left_out(path)) {
      entry.disable_recursion_pending();
      continue;
    }
    struct stat status {};
    if (::lstat(path.c_str(), &status) == 0) {
      kb += static_cast<std::int64_t>(status.st_blocks) / 2;
    }
  }
  return kb;
}

/// One process's footprint (kB, except the counts).
struct ProcessMemory {
  std::int64_t rss_anon_kb = -1;   // private memory it touched: heap, stacks
  std::int64_t rss_shmem_kb = -1;  // shared pages it touched: segments, log ring
  std::int64_t vm_size_kb = -1;    // everything mapped, touched or not
  std::int64_t threads = -1;
  std::int64_t fds = -1;
};

inline std::int64_t count_entries(const std::string& folder) {
  DIR* dir = ::opendir(folder.c_str());
  if (dir == nullptr) {
    return -1;
  }
  std::int64_t count = 0;
  // Single-threaded supervisor, a stream of its own.
  while (const dirent* entry = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe)
    count += entry->d_name[0] == '.' ? 0 : 1;
  }
  ::closedir(dir);
  return count;
}

inline ProcessMemory process_memory(pid_t pid) {
  const std::string folder = "/proc/" + std::to_string(pid);
  ProcessMemory memory;
  memory.rss_anon_kb = proc_field(folder + "/status", "RssAnon:");
  memory.rss_shmem_kb = proc_field(folder + "/status", "RssShmem:");
  memory.vm_size_kb = proc_field(folder + "/status", "VmSize:");
  memory.threads = proc_field(folder + "/status", "Threads:");
  memory.fds = count_entries(folder + "/fd");
  return memory;
}

inline std::string read_line(const std::string& path) {
  std::ifstream file(path);
  std::string line;
  std::getline(file, line);
  return line;
}

/// Where each thread of a process is: "name state wait-channel" per thread, e.g.
/// "horus_soak S futex_wait_queue; horus-svc R 0", what a hung process is waiting on.
inline std::string thread_states(pid_t pid) {
  const std::string tasks = "/proc/" + std::to_string(pid) + "/task";
  DIR* dir = ::opendir(tasks.c_str());
  if (dir == nullptr) {
    return "(gone)";
  }
  std::string states;
  while (const dirent* entry = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe)
    if (entry->d_name[0] == '.') {
      continue;
    }
    const std::string task = tasks + "/" + entry->d_name;
    const std::string stat = read_line(task + "/stat");
    // "tid (name) S ...": the name may hold spaces, the state follows its closing parenthesis.
    const std::size_t close = stat.rfind(')');
    const char state =
        close != std::string::npos && close + 2 < stat.size() ? stat[close + 2] : '?';
    states += (states.empty() ? "" : "; ") + read_line(task + "/comm") + " " + state + " " +
              read_line(task + "/wchan");
  }
  ::closedir(dir);
  return states;
}

}  // namespace soak
