// Per-stage timing without the heap: a fixed histogram of durations in 10 µs
// bins up to 200 ms (and one overflow bin), from which the loop reports
// medians, p99 and maxima.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>

namespace markloop::ecu {

class TimingHistogram {
 public:
  static constexpr std::int64_t kBinNs = 10'000;
  static constexpr std::size_t kBins = 20'000;  // 200 ms

  void add(std::chrono::nanoseconds d) noexcept {
    const std::int64_t ns = d.count() < 0 ? 0 : d.count();
    const auto bin = static_cast<std::size_t>(ns / kBinNs);
    ++bins_[bin < kBins ? bin : kBins];
    ++count_;
    if (ns > max_ns_) max_ns_ = ns;
    sum_ns_ += ns;
  }
  std::uint64_t count() const noexcept { return count_; }
  std::int64_t max_ns() const noexcept { return max_ns_; }
  double mean_ns() const noexcept { return count_ == 0 ? 0.0 : double(sum_ns_) / double(count_); }
  // Upper edge of the bin holding the q-quantile (0..1); the overflow bin
  // reports the maximum.
  std::int64_t quantile_ns(double q) const noexcept {
    if (count_ == 0) return 0;
    const auto rank = static_cast<std::uint64_t>(q * double(count_ - 1)) + 1;
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBins; ++i) {
      seen += bins_[i];
      if (seen >= rank) return static_cast<std::int64_t>(i + 1) * kBinNs;
    }
    return max_ns_;
  }

 private:
  std::array<std::uint32_t, kBins + 1> bins_{};
  std::uint64_t count_ = 0;
  std::int64_t max_ns_ = 0;
  std::int64_t sum_ns_ = 0;
};

}  // namespace markloop::ecu
