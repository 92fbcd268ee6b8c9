// The segments this process created, and their removal once nobody uses them.
#include "horus/internal/created_segments.hpp"

#include <fcntl.h>
#include <sys/stat.h>

#include <exception>
#include <mutex>
#include <set>
#include <tuple>

namespace horus::detail {
namespace {

struct CreatedSegments {
  std::mutex mutex;
  std::set<std::tuple<std::string, std::string, unsigned>> segments;  // namespace, name, mode
};

CreatedSegments& created() {
  static CreatedSegments* const instance = new CreatedSegments();  // outlives static teardown
  return *instance;
}

}  // namespace

void remember_created_segment(std::string_view namespace_name, const std::string& name,
                              unsigned mode) {
  CreatedSegments& created_now = created();
  std::lock_guard lock(created_now.mutex);
  created_now.segments.emplace(
      namespace_name.empty() ? current_namespace() : std::string(namespace_name), name, mode);
}

std::size_t remove_created_segments_nobody_uses() {
  CreatedSegments& created_now = created();
  std::lock_guard lock(created_now.mutex);
  std::size_t removed = 0;
  for (auto it = created_now.segments.begin(); it != created_now.segments.end();) {
    const auto& [namespace_name, name, mode] = *it;
    const NamespaceFolder folder = open_namespace_folder(namespace_name, mode, false);
    struct stat info {};
    if (folder.descriptor.get() >= 0 && remove_if_abandoned(folder, name)) {
      ++removed;
      it = created_now.segments.erase(it);
    } else if (folder.descriptor.get() < 0 ||
               ::fstatat(folder.descriptor.get(), name.c_str(), &info, AT_SYMLINK_NOFOLLOW) != 0) {
      it = created_now.segments.erase(it);  // removed by someone else meanwhile
    } else {
      ++it;
    }
  }
  return removed;
}

}  // namespace horus::detail
