#pragma once
/// @file fixed_ring.hpp
/// Fixed-capacity ring buffer (FIFO): the capacity is part of the type, the storage is inline,
/// nothing is ever allocated (in the spirit of ETL's `circular_buffer`).
///
/// `FixedRing<T, N>` keeps at most N elements in insertion order: `push` appends a newest element
/// and, when the ring is full, first drops the oldest one (a history that keeps the recent past);
/// `tryPush` refuses instead (`Status::CapacityExceeded`, counted in `refusedCount()` like
/// `FixedVector`) for a queue that must not lose what it holds. `ring[0]` is the oldest element,
/// `ring[size() - 1]` the newest.
///
/// Like `FixedVector`, the storage is uninitialised, aligned raw memory (raw_storage.hpp): an
/// element is constructed in place when it is pushed and destroyed when it is dropped, popped or
/// cleared, or when the ring is destroyed; constructing a ring constructs no `T`, and `T` needs no
/// default constructor. Element access (`operator[]`, `front()`, `back()`) is checked by
/// `AGV_ASSERT` in debug builds (assert.hpp). Every operation is O(1) except `clear()`, copying and
/// destruction (O(size()), O(1) for `clear()` of a trivially destructible `T`).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>

#include "agv/core/assert.hpp"
#include "agv/core/raw_storage.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// Ring buffer of at most `N` elements of `T`, stored inline; see the file comment.
template <typename T, std::size_t N>
class FixedRing {
  static_assert(N > 0, "FixedRing capacity must be positive");

 public:
  using value_type = T;
  using size_type = std::size_t;
  /// The capacity.
  static constexpr std::size_t kCapacity = N;

  /// An empty ring; constructs no element.
  FixedRing() noexcept : storage_() {}
  /// Copies the live elements of `other` in their order (and its refusal count).
  FixedRing(const FixedRing& other) noexcept : storage_() { copyFrom(other); }
  /// Replaces the content with the live elements of `other` in their order (and its refusal count).
  FixedRing& operator=(const FixedRing& other) noexcept {
    if (this != &other) {
      clear();
      copyFrom(other);
    }
    return *this;
  }
  /// Destroys the live elements.
  ~FixedRing() { clear(); }

  /// Number of live elements.
  std::size_t size() const noexcept { return size_; }
  /// Maximum number of elements, `N`.
  static constexpr std::size_t capacity() noexcept { return N; }
  /// True when there is no element.
  bool empty() const noexcept { return size_ == 0; }
  /// True when `size() == capacity()`: `push` then drops the oldest element, `tryPush` refuses.
  bool full() const noexcept { return size_ == N; }

  /// Number of elements `tryPush` refused because the ring was full, since construction or the
  /// last `resetRefusedCount()`. Neither `push` (which drops the oldest instead) nor `clear()`
  /// changes it.
  std::uint32_t refusedCount() const noexcept { return refused_; }
  /// Sets `refusedCount()` to 0.
  void resetRefusedCount() noexcept { refused_ = 0; }

  /// Appends a copy of `value` as the newest element. When the ring is full the oldest element is
  /// destroyed first to make room; returns true in that case (false when nothing was dropped).
  bool push(const T& value) noexcept {
    if (size_ == N) {
      T& oldest = storage_.object(head_);
      // The newest takes the oldest's slot. Pushing the oldest element itself leaves the slot as it
      // is: it already holds that value.
      if (std::addressof(oldest) != std::addressof(value)) {
        oldest.~T();
        ::new (static_cast<void*>(storage_.slot(head_))) T(value);
      }
      head_ = wrap(head_ + 1);
      return true;
    }
    ::new (static_cast<void*>(storage_.slot(wrap(head_ + size_)))) T(value);
    ++size_;
    return false;
  }
  /// Appends a copy of `value` as the newest element if there is room; when full the ring is left
  /// unchanged, the refusal is counted and `CapacityExceeded` returned.
  Status tryPush(const T& value) noexcept {
    if (size_ == N) {
      ++refused_;
      return Status::CapacityExceeded;
    }
    (void)push(value);
    return Status::Ok;
  }
  /// Removes (destroys) the oldest element; no effect when empty.
  void pop_front() noexcept {
    if (size_ > 0) {
      storage_.object(head_).~T();
      head_ = wrap(head_ + 1);
      --size_;
    }
  }
  /// Removes (destroys) every element.
  void clear() noexcept {
    const std::size_t head = head_;
    const std::size_t n = size_;
    head_ = 0;
    size_ = 0;
    if constexpr (!std::is_trivially_destructible_v<T>) {
      for (std::size_t k = 0; k < n; ++k) {
        storage_.object(wrap(head + k)).~T();
      }
    }
  }

  /// Element `k` counted from the oldest (0) to the newest (`size() - 1`); precondition
  /// `k < size()` (`AGV_ASSERT` in debug builds, unchecked otherwise).
  T& operator[](std::size_t k) noexcept {
    AGV_ASSERT(k < size_);
    return storage_.object(wrap(head_ + k));
  }
  /// Element `k` counted from the oldest (0) to the newest (`size() - 1`); precondition
  /// `k < size()` (`AGV_ASSERT` in debug builds, unchecked otherwise).
  const T& operator[](std::size_t k) const noexcept {
    AGV_ASSERT(k < size_);
    return storage_.object(wrap(head_ + k));
  }
  /// Oldest element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  T& front() noexcept {
    AGV_ASSERT(size_ > 0);
    return storage_.object(head_);
  }
  /// Oldest element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  const T& front() const noexcept {
    AGV_ASSERT(size_ > 0);
    return storage_.object(head_);
  }
  /// Newest element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  T& back() noexcept {
    AGV_ASSERT(size_ > 0);
    return storage_.object(wrap(head_ + size_ - 1));
  }
  /// Newest element; precondition `!empty()` (`AGV_ASSERT` in debug builds).
  const T& back() const noexcept {
    AGV_ASSERT(size_ > 0);
    return storage_.object(wrap(head_ + size_ - 1));
  }

 private:
  /// Slot of position `i` in [0, 2N): one conditional subtraction instead of a division.
  static std::size_t wrap(std::size_t i) noexcept { return i < N ? i : i - N; }
  /// Appends copies of `other`'s elements, oldest first (this ring is empty), and its count.
  void copyFrom(const FixedRing& other) noexcept {
    const std::size_t n = other.size_;
    for (std::size_t k = 0; k < n; ++k) {
      ::new (static_cast<void*>(storage_.slot(k))) T(other[k]);
    }
    size_ = n;
    refused_ = other.refused_;
  }

  detail::RawStorage<T, N> storage_;
  std::size_t head_ = 0;  ///< slot of the oldest element
  std::size_t size_ = 0;
  std::uint32_t refused_ = 0;
};

}  // namespace agv
