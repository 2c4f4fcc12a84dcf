#pragma once
/// @file raw_storage.hpp
/// Uninitialised, suitably aligned inline storage for the fixed-capacity containers
/// (`FixedVector`, `FixedRing`): room for N objects of `T`, none of which exists until the owning
/// container constructs it (placement new) and which it destroys again. Not an interface for
/// algorithm code.

#include <cstddef>
#include <new>

namespace agv::detail {

/// Bytes for `N` objects of `T`, aligned for `T`. Constructing it constructs no `T` and does not
/// touch the bytes; the owner tracks which slots hold live objects.
template <typename T, std::size_t N>
class RawStorage {
 public:
  /// Leaves the bytes uninitialised. Deliberately user-provided (not `= default`): value-
  /// initialisation of a defaulted constructor would zero all N slots first.
  RawStorage() noexcept {}                            // NOLINT(modernize-use-equals-default)
  RawStorage(const RawStorage&) = delete;             // the owner copies its live objects itself
  RawStorage& operator=(const RawStorage&) = delete;  // idem
  ~RawStorage() = default;                            // the owner destroys its live objects first

  /// Address of slot `i` (i <= N), for constructing an object there or as the base of an array
  /// of live objects.
  T* slot(std::size_t i) noexcept { return reinterpret_cast<T*>(bytes_ + i * sizeof(T)); }
  /// The live object in slot `i` (precondition: the owner constructed one there).
  T& object(std::size_t i) noexcept { return *std::launder(slot(i)); }
  /// The live object in slot `i` (precondition: the owner constructed one there).
  const T& object(std::size_t i) const noexcept {
    return *std::launder(reinterpret_cast<const T*>(bytes_ + i * sizeof(T)));
  }

 private:
  alignas(T) unsigned char bytes_[sizeof(T) * N];
};

}  // namespace agv::detail
