#pragma once
// Whether this test binary runs under AddressSanitizer (tools/ci-sanitizers.sh builds every
// target with -fsanitize=address). ASan replaces the allocator (redzones, a quarantine of freed
// blocks), so resident-memory figures of a sanitized process are not the program's: tests that
// assert memory bounds skip that assertion there; the Release run (./test.sh) checks it.

namespace mav::test_support {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kUnderAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kUnderAddressSanitizer = true;
#else
inline constexpr bool kUnderAddressSanitizer = false;
#endif
#else
inline constexpr bool kUnderAddressSanitizer = false;
#endif

}  // namespace mav::test_support
