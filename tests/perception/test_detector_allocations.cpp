// Proves detect() does not touch the heap: operator new is replaced, and so
// are the C allocation functions (OpenCV allocates matrices with malloc and
// posix_memalign), all counted while frames are processed.
#include <atomic>
#include <cstdlib>
#include <new>

#include <catch2/catch_test_macros.hpp>

#include "perception/marking_detector.hpp"
#include "synthetic_road.hpp"

// AddressSanitizer owns malloc: under it only operator new is counted (the
// plain build counts everything).
#if defined(__SANITIZE_ADDRESS__)
#define MARKLOOP_COUNT_C_ALLOCATIONS 0
#else
#define MARKLOOP_COUNT_C_ALLOCATIONS 1
#endif

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {
std::atomic<bool> counting{false};
std::atomic<std::size_t> allocations{0};
void count() {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

#if MARKLOOP_COUNT_C_ALLOCATIONS
extern "C" {
void* malloc(std::size_t size) {
  count();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  count();
  return __libc_realloc(p, size);
}
void free(void* p) { __libc_free(p); }
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  count();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
}
#endif

void* operator new(std::size_t size) {
  count();
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace markloop::perception;
using markloop::perception::testing::GroundRect;
using markloop::perception::testing::render_road;

TEST_CASE("the counters see C, C++ and OpenCV allocations", "[perception][memory]") {
  allocations = 0;
  counting = true;
  void* p = std::malloc(64);
  int* q = new int(3);
  cv::Mat m(64, 64, CV_8UC1);
  counting = false;
  std::free(p);
  delete q;
  // new + malloc + the Mat's buffer; under ASan only the new.
  CHECK(allocations.load() >= (MARKLOOP_COUNT_C_ALLOCATIONS ? 3u : 1u));
  allocations = 0;
}

TEST_CASE("detect() allocates nothing, frame after frame", "[perception][memory]") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // Frames with markings moving towards the car, lane lines and a crowd of
  // specks, so that every stage (labelling, grouping, features, classifier)
  // runs.
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 12; ++k) {
    const double x = 18.0 - 1.2 * k;
    std::vector<GroundRect> paint = {{x, x + 2.4, 0.5, 1.1},       {x, x + 2.4, -0.2, 0.3},
                                     {x - 1, x + 2, -3.0, -2.0},   {3.0, 25.0, 1.7, 1.85},
                                     {3.0, 25.0, -1.85, -1.7},     {x + 3, x + 3.4, -5, 5}};
    for (int s = 0; s < 30; ++s) {
      const double sx = 4.0 + 0.5 * s, sy = -5.0 + 0.33 * s;
      paint.push_back({sx, sx + 0.25, sy, sy + 0.2});
    }
    frames.push_back(render_road(camera, paint));
  }
  detector.detect(frames[0]);  // first call: nothing lazy may remain either
  std::size_t detections = 0, candidates = 0;
  counting = true;
  for (int round = 0; round < 10; ++round)
    for (const cv::Mat& frame : frames) {
      detections += detector.detect(frame).size();
      candidates += detector.candidates().size();
    }
  counting = false;
  CHECK(allocations.load() == 0);
  CHECK(candidates > 0);
  CHECK(detector.counters().frames == 121);
  (void)detections;
}
