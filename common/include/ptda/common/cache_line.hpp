#pragma once

#include <cstddef>

namespace ptda {

/// Our own cache-line size. std::hardware_destructive_interference_size is 256 on GCC 12 aarch64
/// (and warns in headers); Cortex-A53/A72 and x86 lines are 64 bytes.
inline constexpr std::size_t kCacheLineBytes = 64;

}  // namespace ptda
