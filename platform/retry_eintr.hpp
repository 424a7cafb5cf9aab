// Internal to platform/: the one EINTR loop every syscall wrapper uses.
#pragma once

#include <cerrno>

namespace markloop::platform::detail {

// Calls `f` until it does not fail with EINTR. `f` returns -1 on failure.
template <typename F>
auto retry_eintr(F&& f) noexcept {
  for (;;) {
    auto r = f();
    if (r != -1 || errno != EINTR) return r;
  }
}

}  // namespace markloop::platform::detail
