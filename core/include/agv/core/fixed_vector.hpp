#pragma once
/// @file fixed_vector.hpp
/// Fixed-capacity vector: the capacity is part of the type, the storage is inline, nothing is
/// ever allocated.
///
/// `FixedVector<T, N>` owns storage for N elements. It derives from `IVector<T>`, which carries the
/// capacity at run time, so one function taking `IVector<T>&` (or `const IVector<T>&`) serves
/// vectors of every capacity without templates (the pattern of ETL's `ivector`).
///
/// Element storage is a `std::array<T, N>` of default-constructed objects: `T` must be
/// default-constructible and copy-assignable (points, keypoints, landmarks, Eigen fixed-size types).
/// Elements past `size()` keep whatever they last held; `clear()` only resets the size.
///
/// A push onto a full vector is refused with `Status::CapacityExceeded` and counted in
/// `refusedCount()`, so that a caller can report how much data it could not keep.

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "agv/core/status.hpp"

namespace agv {

/// Capacity-independent interface of a `FixedVector`. Not constructible on its own.
template <typename T>
class IVector {
 public:
  using value_type = T;
  using size_type = std::size_t;
  using iterator = T*;
  using const_iterator = const T*;

  IVector(const IVector&) = delete;             // would slice; copy the FixedVector instead
  IVector& operator=(const IVector&) = delete;  // use assign()

  /// Number of live elements.
  std::size_t size() const noexcept { return size_; }
  /// Maximum number of elements (fixed for the lifetime of the object).
  std::size_t capacity() const noexcept { return capacity_; }
  /// Free slots.
  std::size_t available() const noexcept { return capacity_ - size_; }
  bool empty() const noexcept { return size_ == 0; }
  bool full() const noexcept { return size_ == capacity_; }

  /// Number of elements refused because the vector was full, since construction or the last
  /// `resetRefusedCount()`. `clear()` does not reset it.
  std::uint32_t refusedCount() const noexcept { return refused_; }
  void resetRefusedCount() noexcept { refused_ = 0; }

  T* data() noexcept { return data_; }
  const T* data() const noexcept { return data_; }
  iterator begin() noexcept { return data_; }
  iterator end() noexcept { return data_ + size_; }
  const_iterator begin() const noexcept { return data_; }
  const_iterator end() const noexcept { return data_ + size_; }

  /// Unchecked element access; `i < size()` is the caller's precondition.
  T& operator[](std::size_t i) noexcept { return data_[i]; }
  const T& operator[](std::size_t i) const noexcept { return data_[i]; }
  /// Checked element access: nullptr when `i >= size()`.
  T* at(std::size_t i) noexcept { return i < size_ ? data_ + i : nullptr; }
  const T* at(std::size_t i) const noexcept { return i < size_ ? data_ + i : nullptr; }
  /// First / last element; precondition `!empty()`.
  T& front() noexcept { return data_[0]; }
  const T& front() const noexcept { return data_[0]; }
  T& back() noexcept { return data_[size_ - 1]; }
  const T& back() const noexcept { return data_[size_ - 1]; }

  /// Appends a copy of `value`; `CapacityExceeded` (and counted) when full.
  Status push_back(const T& value) noexcept {
    if (size_ == capacity_) {
      ++refused_;
      return Status::CapacityExceeded;
    }
    data_[size_++] = value;
    return Status::Ok;
  }
  /// Appends a value-initialised element and returns it for filling in place; nullptr (and
  /// counted) when full.
  T* append() noexcept {
    if (size_ == capacity_) {
      ++refused_;
      return nullptr;
    }
    data_[size_] = T{};
    return data_ + size_++;
  }
  /// Removes the last element; no effect when empty.
  void pop_back() noexcept {
    if (size_ > 0) {
      --size_;
    }
  }
  /// Removes every element (O(1)).
  void clear() noexcept { size_ = 0; }

  /// Sets the size to `n`; new elements are value-initialised. `CapacityExceeded` if n > capacity.
  Status resize(std::size_t n) noexcept {
    if (n > capacity_) {
      return Status::CapacityExceeded;
    }
    for (std::size_t i = size_; i < n; ++i) {
      data_[i] = T{};
    }
    size_ = n;
    return Status::Ok;
  }

  /// Inserts `value` before position `i` (i <= size()), shifting the tail. O(size()).
  Status insert(std::size_t i, const T& value) noexcept {
    if (i > size_) {
      return Status::OutOfRange;
    }
    if (size_ == capacity_) {
      ++refused_;
      return Status::CapacityExceeded;
    }
    for (std::size_t k = size_; k > i; --k) {
      data_[k] = data_[k - 1];
    }
    data_[i] = value;
    ++size_;
    return Status::Ok;
  }
  /// Removes element `i`, keeping the order of the rest. O(size()).
  Status erase(std::size_t i) noexcept {
    if (i >= size_) {
      return Status::OutOfRange;
    }
    for (std::size_t k = i + 1; k < size_; ++k) {
      data_[k - 1] = data_[k];
    }
    --size_;
    return Status::Ok;
  }
  /// Removes element `i` by moving the last element into its place. O(1); order not kept.
  Status eraseUnordered(std::size_t i) noexcept {
    if (i >= size_) {
      return Status::OutOfRange;
    }
    data_[i] = data_[size_ - 1];
    --size_;
    return Status::Ok;
  }

  /// Replaces the content with a copy of `other`. If `other` does not fit, copies the first
  /// `capacity()` elements, counts the rest as refused and returns `CapacityExceeded`.
  Status assign(const IVector& other) noexcept {
    if (&other == this) {
      return Status::Ok;
    }
    const std::size_t n = other.size_ <= capacity_ ? other.size_ : capacity_;
    for (std::size_t i = 0; i < n; ++i) {
      data_[i] = other.data_[i];
    }
    size_ = n;
    if (n < other.size_) {
      refused_ += static_cast<std::uint32_t>(other.size_ - n);
      return Status::CapacityExceeded;
    }
    return Status::Ok;
  }

 protected:
  IVector(T* storage, std::size_t capacity) noexcept : data_(storage), capacity_(capacity) {}
  ~IVector() = default;
  void copyCountsFrom(const IVector& other) noexcept {
    size_ = other.size_;
    refused_ = other.refused_;
  }

 private:
  T* data_;
  std::size_t size_ = 0;
  std::size_t capacity_;
  std::uint32_t refused_ = 0;
};

namespace detail {
/// Inline element storage; a base class so that it is constructed before IVector takes its address.
template <typename T, std::size_t N>
struct FixedVectorStorage {
  std::array<T, N> storage_{};
};
}  // namespace detail

/// Vector of at most `N` elements of `T`, stored inline.
template <typename T, std::size_t N>
class FixedVector : private detail::FixedVectorStorage<T, N>, public IVector<T> {
  static_assert(N > 0, "FixedVector capacity must be positive");
  static_assert(std::is_default_constructible_v<T>, "FixedVector<T, N> needs a default-constructible T");
  using Storage = detail::FixedVectorStorage<T, N>;

 public:
  static constexpr std::size_t kCapacity = N;

  FixedVector() noexcept : Storage(), IVector<T>(Storage::storage_.data(), N) {}
  FixedVector(const FixedVector& other) noexcept : Storage(), IVector<T>(Storage::storage_.data(), N) {
    copyFrom(other);
  }
  FixedVector& operator=(const FixedVector& other) noexcept {
    if (this != &other) {
      copyFrom(other);
    }
    return *this;
  }
  ~FixedVector() = default;

 private:
  void copyFrom(const FixedVector& other) noexcept {
    for (std::size_t i = 0; i < other.size(); ++i) {
      Storage::storage_[i] = other.Storage::storage_[i];
    }
    this->copyCountsFrom(other);
  }
};

}  // namespace agv
