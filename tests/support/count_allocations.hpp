// Counts heap allocations, for tests that prove a code path leaves the heap
// alone. This header DEFINES the global allocation functions (replacements),
// which a program may define only once: include it in exactly one
// translation unit of a test binary, and from no other header (a second
// inclusion in the same binary fails to link: multiple definitions of
// operator new).
//
// By default it replaces operator new, new[], delete and delete[]. With
//   #define MARKLOOP_COUNT_C_ALLOCATIONS 1
// before the include it also replaces malloc, calloc, realloc, free,
// posix_memalign, aligned_alloc and memalign (through glibc's __libc_*
// functions), which catches what C code and OpenCV allocate. Then an operator
// new counts twice (itself and its malloc): compare with 0 or a lower bound.
// AddressSanitizer owns malloc: under it the C functions are never replaced
// and only operator new is counted (markloop::test::counts_c_allocations).
//
// Use:
//   AllocationCounter heap;  // from 0, counting
//   ...code under test...    // no Catch macros in here: they allocate
//   const std::size_t allocations = heap.stop();
//   CHECK(allocations == 0);
#pragma once

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(MARKLOOP_COUNT_C_ALLOCATIONS) && MARKLOOP_COUNT_C_ALLOCATIONS && !defined(__SANITIZE_ADDRESS__)
#define MARKLOOP_REPLACES_C_ALLOCATIONS 1
#else
#define MARKLOOP_REPLACES_C_ALLOCATIONS 0
#endif

namespace markloop::test {

// Whether malloc and the other C functions are counted too.
inline constexpr bool counts_c_allocations = MARKLOOP_REPLACES_C_ALLOCATIONS != 0;

namespace detail {
inline std::atomic<bool> counting{false};
inline std::atomic<std::size_t> allocations{0};

inline void count_allocation() noexcept {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace detail

// Counts the allocations made while it is alive and not paused; starts from
// zero. One at a time: the count is global.
class AllocationCounter {
 public:
  AllocationCounter() noexcept {
    detail::allocations = 0;
    detail::counting = true;
  }
  ~AllocationCounter() { detail::counting = false; }
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  // Leaves out what happens until resume() (e.g. a simulator making inputs).
  void pause() noexcept { detail::counting = false; }
  void resume() noexcept { detail::counting = true; }
  // Stops counting; the allocations counted.
  std::size_t stop() noexcept {
    pause();
    return count();
  }
  std::size_t count() const noexcept { return detail::allocations.load(); }
};

}  // namespace markloop::test

#if MARKLOOP_REPLACES_C_ALLOCATIONS
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);

void* malloc(std::size_t size) {
  markloop::test::detail::count_allocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  markloop::test::detail::count_allocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  markloop::test::detail::count_allocation();
  return __libc_realloc(p, size);
}
void free(void* p) {
  __libc_free(p);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  markloop::test::detail::count_allocation();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  markloop::test::detail::count_allocation();
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  markloop::test::detail::count_allocation();
  return __libc_memalign(alignment, size);
}
}
#endif

// Not inline (replacements may not be): hence the one-translation-unit rule.
void* operator new(std::size_t size) {
  markloop::test::detail::count_allocation();
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
  return operator new(size);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
