// What the lifecycle tests' nodes did, in order, from whichever thread ran them.
#pragma once

#include <algorithm>
#include <cstddef>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace horus_test {

/// Every lifecycle call appends "<what>:<node>" ("init:motor", "shutdown:lidar").
class Journal {
 public:
  void add(std::string entry) {
    std::lock_guard lock(mutex_);
    entries_.push_back(std::move(entry));
  }
  std::vector<std::string> entries() const {
    std::lock_guard lock(mutex_);
    return entries_;
  }
  /// The entries starting with `prefix`, in order.
  std::vector<std::string> only(const std::string& prefix) const {
    std::vector<std::string> out;
    for (const auto& e : entries()) {
      if (e.starts_with(prefix)) out.push_back(e);
    }
    return out;
  }
  /// Where `entry` first stands, or the number of entries when it does not.
  std::size_t index_of(const std::string& entry) const {
    const auto all = entries();
    return static_cast<std::size_t>(std::find(all.begin(), all.end(), entry) - all.begin());
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> entries_;
};

}  // namespace horus_test
