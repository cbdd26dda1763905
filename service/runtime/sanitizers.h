#pragma once
// Which sanitizer this translation unit is built with (GCC defines
// __SANITIZE_*__, Clang answers __has_feature). The runtime adapts where a
// sanitizer cannot follow it: TSan does not model standalone fences, and
// locking all memory would try to lock the sanitizers' terabytes of shadow.
#if defined(__SANITIZE_THREAD__)
#define RILO_HAS_TSAN 1
#endif
#if defined(__SANITIZE_ADDRESS__)
#define RILO_HAS_ASAN 1
#endif
#if defined(__has_feature)
#if __has_feature(thread_sanitizer) && !defined(RILO_HAS_TSAN)
#define RILO_HAS_TSAN 1
#endif
#if __has_feature(address_sanitizer) && !defined(RILO_HAS_ASAN)
#define RILO_HAS_ASAN 1
#endif
#endif

namespace rilo {

#if defined(RILO_HAS_TSAN) || defined(RILO_HAS_ASAN)
inline constexpr bool kSanitizerBuild = true;
#else
inline constexpr bool kSanitizerBuild = false;
#endif

}  // namespace rilo
