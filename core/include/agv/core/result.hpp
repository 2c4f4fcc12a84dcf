#pragma once
/// @file result.hpp
/// `Result<T>`: a value or the `Status` that explains its absence. No exceptions, no heap.

#include <type_traits>
#include <utility>

#include "agv/core/status.hpp"

namespace agv {

/// A value of type `T`, or a failure `Status`.
///
/// `T` must be default-constructible: the value slot always exists (it holds `T{}` on failure),
/// which keeps the type trivially copyable when `T` is and avoids any hidden construction rules.
/// Reading `value()` of a failed result returns that default value; check `ok()` first.
template <typename T>
class [[nodiscard]] Result {
  static_assert(std::is_default_constructible_v<T>, "Result<T> needs a default-constructible T");
  static_assert(!std::is_same_v<T, Status>, "use Status directly instead of Result<Status>");

 public:
  /// A successful result holding `value`.
  constexpr Result(const T& value) noexcept(
      std::is_nothrow_copy_constructible_v<T>)  // NOLINT(google-explicit-constructor)
      : value_(value) {}
  /// A successful result holding `value`.
  constexpr Result(T&& value) noexcept(std::is_nothrow_move_constructible_v<T>)  // NOLINT(google-explicit-constructor)
      : value_(std::move(value)) {}
  /// A failed result. `status` must not be `Status::Ok` (it is turned into `InvalidArgument`).
  constexpr Result(Status status) noexcept  // NOLINT(google-explicit-constructor)
      : status_(status == Status::Ok ? Status::InvalidArgument : status) {}

  /// True on success.
  constexpr bool ok() const noexcept { return status_ == Status::Ok; }
  constexpr explicit operator bool() const noexcept { return ok(); }
  /// `Status::Ok` on success, otherwise the failure reason.
  constexpr Status status() const noexcept { return status_; }
  /// The value (meaningful only when `ok()`).
  constexpr const T& value() const& noexcept { return value_; }
  constexpr T& value() & noexcept { return value_; }
  /// The value when `ok()`, otherwise `fallback`.
  constexpr T valueOr(const T& fallback) const noexcept { return ok() ? value_ : fallback; }

 private:
  Status status_ = Status::Ok;
  T value_{};
};

}  // namespace agv
