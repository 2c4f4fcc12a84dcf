// Allocates on purpose: the MCU heap check must refuse this image (its test is WILL_FAIL).
#include <cstdlib>

int main() {
  volatile int* p = static_cast<int*>(std::malloc(sizeof(int)));
  return p == nullptr ? 1 : 0;
}
