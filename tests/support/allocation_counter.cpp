// Replacements of the global allocator that count each allocation (allocation_counter.hpp):
// linked into a test executable, they replace the library's for the whole process.
#include "allocation_counter.hpp"

#include <cstdlib>
#include <new>

std::atomic<long> horus_test::allocations{0};

// GCC pairs the library's inline new with these frees and warns, though the replaced operator
// new does call malloc.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
  horus_test::allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
