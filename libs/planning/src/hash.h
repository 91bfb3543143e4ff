#pragma once
// FNV-1a 64-bit hashing (internal to libs/planning): the map fingerprint and the roadmap file's
// checksum, the same function as the .mavocc format's (docs/formats.md):
//   h = 0xcbf29ce484222325; for each byte b: h = (h XOR b) * 0x100000001b3 (mod 2^64).

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include <Eigen/Core>

namespace mav::planning {

class Fnv1a64 {
 public:
  void AddBytes(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * 0x100000001b3ull;
  }
  template <typename T>
  void Add(const T& value) {
    if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) {
      AddBytes(value.data(), sizeof(typename T::Scalar) * value.size());
    } else {
      static_assert(std::is_trivially_copyable_v<T>);
      AddBytes(&value, sizeof(T));
    }
  }
  uint64_t value() const { return h_; }

 private:
  uint64_t h_ = 0xcbf29ce484222325ull;
};

}  // namespace mav::planning
