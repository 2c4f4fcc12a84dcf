#pragma once
/// @file span.hpp
/// `Span<T>`: a non-owning pointer + length view (C++17 has no std::span).
/// Used for raw buffers (telegrams, beam arrays) whose storage the caller owns.

#include <cstddef>

namespace agv {

template <typename T>
class Span {
 public:
  constexpr Span() noexcept = default;
  constexpr Span(T* data, std::size_t size) noexcept : data_(data), size_(size) {}
  template <std::size_t N>
  constexpr Span(T (&array)[N]) noexcept : data_(array), size_(N) {}  // NOLINT(google-explicit-constructor)
  /// Any contiguous container with data() and size() (FixedVector, std::array, ...).
  template <typename C, typename = decltype(static_cast<T*>(static_cast<C*>(nullptr)->data()))>
  constexpr Span(C& c) noexcept : data_(c.data()), size_(c.size()) {}  // NOLINT(google-explicit-constructor)

  constexpr T* data() const noexcept { return data_; }
  constexpr std::size_t size() const noexcept { return size_; }
  constexpr bool empty() const noexcept { return size_ == 0; }
  constexpr T& operator[](std::size_t i) const noexcept { return data_[i]; }
  constexpr T* begin() const noexcept { return data_; }
  constexpr T* end() const noexcept { return data_ + size_; }
  /// The sub-view [offset, offset + count), clamped to this span.
  constexpr Span subspan(std::size_t offset, std::size_t count) const noexcept {
    if (offset > size_) {
      offset = size_;
    }
    if (count > size_ - offset) {
      count = size_ - offset;
    }
    return Span(data_ + offset, count);
  }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace agv
