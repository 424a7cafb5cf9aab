// A vector with its capacity fixed at compile time and its storage inline:
// never allocates, so it is safe in the real-time loop.
#pragma once

#include <array>
#include <cassert>
#include <cstddef>
#include <span>

namespace markloop {

template <typename T, std::size_t Capacity>
class FixedVector {
 public:
  static constexpr std::size_t capacity() { return Capacity; }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  bool full() const { return size_ == Capacity; }

  // Returns false (and leaves the vector unchanged) when full.
  bool push_back(const T& value) {
    if (size_ == Capacity) return false;
    items_[size_++] = value;
    return true;
  }
  // Appends a default element and returns it, to be filled in place (no
  // copy of a large element). Precondition: !full().
  T& push_back_slot() {
    assert(size_ < Capacity);
    items_[size_] = T{};
    return items_[size_++];
  }
  void pop_back() {
    assert(size_ > 0);
    --size_;
  }
  void clear() { size_ = 0; }
  void erase_at(std::size_t index) {
    assert(index < size_);
    for (std::size_t i = index + 1; i < size_; ++i) items_[i - 1] = items_[i];
    --size_;
  }

  T& operator[](std::size_t i) {
    assert(i < size_);
    return items_[i];
  }
  const T& operator[](std::size_t i) const {
    assert(i < size_);
    return items_[i];
  }
  T& back() { return (*this)[size_ - 1]; }
  const T& back() const { return (*this)[size_ - 1]; }

  T* begin() { return items_.data(); }
  T* end() { return items_.data() + size_; }
  const T* begin() const { return items_.data(); }
  const T* end() const { return items_.data() + size_; }
  std::span<const T> span() const { return {items_.data(), size_}; }

 private:
  std::array<T, Capacity> items_{};
  std::size_t size_ = 0;
};

}  // namespace markloop
