// Host wall time for the stage timings the library reports.
#pragma once

#include <chrono>

namespace isk::detail {

inline double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace isk::detail
