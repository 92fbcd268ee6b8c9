// The segments this process created, and their removal once nobody uses them.
#include "horus/detail/created_segments.hpp"

#include <sys/stat.h>

#include <mutex>
#include <set>

namespace horus::detail {
namespace {

struct CreatedSegments {
  std::mutex mutex;
  std::set<std::string> paths;
};

CreatedSegments& created() {
  static CreatedSegments* const instance = new CreatedSegments();  // outlives static teardown
  return *instance;
}

}  // namespace

void remember_created_segment(const std::string& path) {
  CreatedSegments& segments = created();
  std::lock_guard lock(segments.mutex);
  segments.paths.insert(path);
}

std::size_t remove_created_segments_nobody_uses() {
  CreatedSegments& segments = created();
  std::lock_guard lock(segments.mutex);
  std::size_t removed = 0;
  for (auto it = segments.paths.begin(); it != segments.paths.end();) {
    struct stat info {};
    if (remove_if_abandoned(*it)) {
      ++removed;
      it = segments.paths.erase(it);
    } else if (::lstat(it->c_str(), &info) != 0) {
      it = segments.paths.erase(it);  // removed by someone else meanwhile
    } else {
      ++it;
    }
  }
  return removed;
}

}  // namespace horus::detail
