// Counts the process's heap allocations, for tests that promise a path allocates nothing.
#pragma once

#include <atomic>

namespace horus_test {

/// Every global operator new so far (allocation_counter.cpp replaces it); compare two reads.
extern std::atomic<long> allocations;

}  // namespace horus_test
