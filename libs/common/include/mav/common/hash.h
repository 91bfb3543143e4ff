#pragma once
// FNV-1a 64-bit hashing, the checksum of the project's binary files (.mavocc, .mavprm) and the
// planning map's fingerprint (docs/formats.md):
//   h = 0xcbf29ce484222325; for each byte b: h = (h XOR b) * 0x100000001b3 (mod 2^64).
// Not cryptographic: it detects corruption and tells maps apart, nothing more.

#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace mav {

class Fnv1a64 {
 public:
  void AddBytes(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * 0x100000001b3ull;
  }
  // The object representation of a trivially copyable value (a number, a fixed-size Eigen
  // vector or matrix).
  template <typename T>
  void Add(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>, "hash the bytes of plain values only");
    AddBytes(&value, sizeof(T));
  }
  uint64_t value() const { return h_; }

  static uint64_t Of(const void* data, size_t n) {
    Fnv1a64 h;
    h.AddBytes(data, n);
    return h.value();
  }

 private:
  uint64_t h_ = 0xcbf29ce484222325ull;
};

}  // namespace mav
