#pragma once
// A test element that counts its constructions and destructions, to check the lifetime rules of
// the fixed-capacity containers (every constructed element is destroyed exactly once, no element
// is constructed before it is added). Portable subset: also used in the Cortex-M7 image.

namespace agv::test {

struct Counted {
  static inline int constructed = 0;
  static inline int destroyed = 0;
  /// Elements alive now.
  static int alive() noexcept { return constructed - destroyed; }
  static void resetCounts() noexcept {
    constructed = 0;
    destroyed = 0;
  }

  int value = -1;
  bool live = true;  // false after destruction: reading a destroyed element shows it

  Counted() noexcept { ++constructed; }
  explicit Counted(int v) noexcept : value(v) { ++constructed; }
  Counted(const Counted& other) noexcept : value(other.value), live(other.live) { ++constructed; }
  Counted& operator=(const Counted& other) noexcept {
    value = other.value;
    return *this;
  }
  ~Counted() {
    // Volatile stores: the compiler may not drop them as dead (the object's lifetime ends here),
    // so a copy made from a destroyed element shows it.
    *static_cast<volatile int*>(&value) = -999;
    *static_cast<volatile bool*>(&live) = false;
    ++destroyed;
  }
};

/// No default constructor: a FixedVector / FixedRing of it must still compile and work.
struct NoDefault {
  explicit NoDefault(int v) noexcept : value(v) {}
  int value;
};

}  // namespace agv::test
