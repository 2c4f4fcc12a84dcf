#pragma once
/// @file fixed_vector.hpp
/// Fixed-capacity vector: the capacity is part of the type, the storage is inline, nothing is
/// ever allocated.
///
/// `FixedVector<T, N>` owns storage for N elements. It derives from `IVector<T>`, which carries the
/// capacity at run time, so one function taking `IVector<T>&` (or `const IVector<T>&`) serves
/// vectors of every capacity without templates (the pattern of ETL's `ivector`).
///
/// The storage is uninitialised, aligned raw memory (raw_storage.hpp): constructing a
/// `FixedVector<T, 1000>` constructs no `T`. An element is constructed in place (placement new)
/// when it is added (`push_back`, `emplace_back`, `append`, `insert`, a growing `resize`,
/// `assign`, a copy) and destroyed when it is removed (`pop_back`, `erase`, `eraseUnordered`, a
/// shrinking `resize`, `clear`, the vector's destruction). Only the live elements `[0, size())`
/// exist: reading or writing past `size()`, also through `data()`, is undefined; grow the vector
/// first (`push_back`, `append`, `resize`). `T` needs a default constructor only for `append()`
/// and `resize()`, and copy/move assignment only for `insert`, `erase`, `eraseUnordered`,
/// `assign` and copy assignment.
///
/// A push onto a full vector is refused with `Status::CapacityExceeded` and counted in
/// `refusedCount()`, so that a caller can report how much data it could not keep.
///
/// Element access (`operator[]`, `front()`, `back()`) is checked by `AGV_ASSERT` in debug builds
/// (assert.hpp) and unchecked otherwise; `at()` is always checked.

#include <cstddef>
#include <cstdint>
#include <new>
#include <type_traits>
#include <utility>

#include "agv/core/assert.hpp"
#include "agv/core/raw_storage.hpp"
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
  /// True when there is no element.
  bool empty() const noexcept { return size_ == 0; }
  /// True when `size() == capacity()`: the next push is refused.
  bool full() const noexcept { return size_ == capacity_; }

  /// Number of elements refused because the vector was full, since construction or the last
  /// `resetRefusedCount()`. `clear()` does not reset it.
  std::uint32_t refusedCount() const noexcept { return refused_; }
  /// Sets `refusedCount()` to 0.
  void resetRefusedCount() noexcept { refused_ = 0; }

  /// The live elements `[0, size())` as a contiguous array (slots past `size()` hold no objects).
  T* data() noexcept { return data_; }
  /// The live elements `[0, size())` as a contiguous array (slots past `size()` hold no objects).
  const T* data() const noexcept { return data_; }
  /// Iterator to the first element.
  iterator begin() noexcept { return data_; }
  /// Iterator past the last live element.
  iterator end() noexcept { return data_ + size_; }
  /// Iterator to the first element.
  const_iterator begin() const noexcept { return data_; }
  /// Iterator past the last live element.
  const_iterator end() const noexcept { return data_ + size_; }

  /// Element `i`; precondition `i < size()` (`AGV_ASSERT` in debug builds, unchecked otherwise).
  T& operator[](std::size_t i) noexcept {
    AGV_ASSERT(i < size_);
    return data_[i];
  }
  /// Element `i`; precondition `i < size()` (`AGV_ASSERT` in debug builds, unchecked otherwise).
  const T& operator[](std::size_t i) const noexcept {
    AGV_ASSERT(i < size_);
    return data_[i];
  }
  /// Checked element access: nullptr when `i >= size()`.
  T* at(std::size_t i) noexcept { return i < size_ ? data_ + i : nullptr; }
  /// Checked element access: nullptr when `i >= size()`.
  const T* at(std::size_t i) const noexcept { return i < size_ ? data_ + i : nullptr; }
  /// First element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  T& front() noexcept {
    AGV_ASSERT(size_ > 0);
    return data_[0];
  }
  /// First element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  const T& front() const noexcept {
    AGV_ASSERT(size_ > 0);
    return data_[0];
  }
  /// Last element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  T& back() noexcept {
    AGV_ASSERT(size_ > 0);
    return data_[size_ - 1];
  }
  /// Last element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  const T& back() const noexcept {
    AGV_ASSERT(size_ > 0);
    return data_[size_ - 1];
  }

  /// Appends a copy of `value`; `CapacityExceeded` (and counted) when full.
  Status push_back(const T& value) noexcept { return emplace_back(value); }
  /// Appends `value` (moved); `CapacityExceeded` (and counted) when full.
  Status push_back(T&& value) noexcept { return emplace_back(std::move(value)); }
  /// Appends an element constructed in place from `args` (`T(args...)`, or `T{args...}` for an
  /// aggregate); `CapacityExceeded` (and counted) when full.
  template <typename... Args>
  Status emplace_back(Args&&... args) noexcept {
    if (size_ == capacity_) {
      ++refused_;
      return Status::CapacityExceeded;
    }
    construct(data_ + size_, std::forward<Args>(args)...);
    ++size_;
    return Status::Ok;
  }
  /// Appends a value-initialised element and returns it for filling in place; nullptr (and
  /// counted) when full.
  T* append() noexcept {
    if (size_ == capacity_) {
      ++refused_;
      return nullptr;
    }
    T* p = data_ + size_;
    construct(p);
    ++size_;
    return p;
  }
  /// Removes (destroys) the last element; no effect when empty.
  void pop_back() noexcept {
    if (size_ > 0) {
      --size_;
      data_[size_].~T();
    }
  }
  /// Removes (destroys) every element: O(size()), O(1) for a trivially destructible `T`.
  void clear() noexcept { shrinkTo(0); }

  /// Sets the size to `n`: elements past `n` are destroyed, new elements are value-initialised.
  /// `CapacityExceeded` (size unchanged, not counted) if n > capacity.
  Status resize(std::size_t n) noexcept {
    if (n > capacity_) {
      return Status::CapacityExceeded;
    }
    if (n <= size_) {
      shrinkTo(n);
      return Status::Ok;
    }
    for (std::size_t k = size_; k < n; ++k) {
      construct(data_ + k);
    }
    size_ = n;
    return Status::Ok;
  }

  /// Inserts `value` before position `i` (i <= size()), shifting the tail. O(size()). `value` may
  /// be an element of this vector.
  Status insert(std::size_t i, const T& value) noexcept {
    if (i > size_) {
      return Status::OutOfRange;
    }
    if (size_ == capacity_) {
      ++refused_;
      return Status::CapacityExceeded;
    }
    if (i == size_) {
      construct(data_ + size_, value);
      ++size_;
      return Status::Ok;
    }
    T copy(value);  // before shifting: `value` may refer to an element that moves
    construct(data_ + size_, std::move(data_[size_ - 1]));
    for (std::size_t k = size_ - 1; k > i; --k) {
      data_[k] = std::move(data_[k - 1]);
    }
    data_[i] = std::move(copy);
    ++size_;
    return Status::Ok;
  }
  /// Removes element `i`, keeping the order of the rest. O(size()).
  Status erase(std::size_t i) noexcept {
    if (i >= size_) {
      return Status::OutOfRange;
    }
    for (std::size_t k = i + 1; k < size_; ++k) {
      data_[k - 1] = std::move(data_[k]);
    }
    pop_back();
    return Status::Ok;
  }
  /// Removes element `i` by moving the last element into its place. O(1); order not kept.
  Status eraseUnordered(std::size_t i) noexcept {
    if (i >= size_) {
      return Status::OutOfRange;
    }
    if (i + 1 != size_) {
      data_[i] = std::move(data_[size_ - 1]);
    }
    pop_back();
    return Status::Ok;
  }

  /// Replaces the content with a copy of `other`. If `other` does not fit, copies the first
  /// `capacity()` elements, counts the rest as refused and returns `CapacityExceeded`.
  Status assign(const IVector& other) noexcept {
    if (&other == this) {
      return Status::Ok;
    }
    const std::size_t n = other.size_ <= capacity_ ? other.size_ : capacity_;
    copyElements(other.data_, n);
    if (n < other.size_) {
      refused_ += static_cast<std::uint32_t>(other.size_ - n);
      return Status::CapacityExceeded;
    }
    return Status::Ok;
  }

 protected:
  /// `storage`: room for `capacity` elements, none of them constructed.
  IVector(T* storage, std::size_t capacity) noexcept : data_(storage), capacity_(capacity) {}
  ~IVector() = default;  // the FixedVector destroys the elements (clear()) before this runs
  /// Copies the elements and the refusal count of `other` (whose size fits this capacity).
  void copyFrom(const IVector& other) noexcept {
    copyElements(other.data_, other.size_);
    refused_ = other.refused_;
  }

 private:
  /// Constructs a `T` from `args` in the raw slot `p`.
  template <typename... Args>
  static void construct(T* p, Args&&... args) noexcept {
    if constexpr (std::is_constructible_v<T, Args&&...>) {
      ::new (static_cast<void*>(p)) T(std::forward<Args>(args)...);
    } else {
      ::new (static_cast<void*>(p)) T{std::forward<Args>(args)...};
    }
  }
  /// Destroys the elements `[n, size())` and sets the size to `n` (n <= size()).
  void shrinkTo(std::size_t n) noexcept {
    const std::size_t end = size_;
    size_ = n;
    if constexpr (!std::is_trivially_destructible_v<T>) {
      for (std::size_t k = n; k < end; ++k) {
        data_[k].~T();
      }
    }
  }
  /// Makes the content a copy of `src[0, n)` (n <= capacity, `src` not this vector's storage):
  /// assigns over the live elements, constructs the rest, destroys the surplus.
  void copyElements(const T* src, std::size_t n) noexcept {
    const std::size_t live = size_ < n ? size_ : n;
    for (std::size_t i = 0; i < live; ++i) {
      data_[i] = src[i];
    }
    if (n <= size_) {
      shrinkTo(n);
      return;
    }
    for (std::size_t i = live; i < n; ++i) {
      construct(data_ + i, src[i]);
    }
    size_ = n;
  }

  T* data_;
  std::size_t size_ = 0;
  std::size_t capacity_;
  std::uint32_t refused_ = 0;
};

/// Vector of at most `N` elements of `T`, stored inline; see the file comment.
template <typename T, std::size_t N>
class FixedVector : private detail::RawStorage<T, N>, public IVector<T> {
  static_assert(N > 0, "FixedVector capacity must be positive");
  using Storage = detail::RawStorage<T, N>;

 public:
  /// The capacity.
  static constexpr std::size_t kCapacity = N;

  /// An empty vector; constructs no element.
  FixedVector() noexcept : Storage(), IVector<T>(Storage::slot(0), N) {}
  /// Copies the live elements of `other` (and its refusal count).
  FixedVector(const FixedVector& other) noexcept : Storage(), IVector<T>(Storage::slot(0), N) { this->copyFrom(other); }
  /// Replaces the content with the live elements of `other` (and its refusal count).
  FixedVector& operator=(const FixedVector& other) noexcept {
    if (this != &other) {
      this->copyFrom(other);
    }
    return *this;
  }
  /// Destroys the live elements.
  ~FixedVector() { this->clear(); }
};

}  // namespace agv
