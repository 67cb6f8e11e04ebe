// Host wall time, in milliseconds: the stage timings the library reports and
// the samples' and benchmarks' own timings, measured one way.
#pragma once

#include <chrono>

namespace isk {

// Milliseconds from `start` to now on the steady clock.
inline double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace isk
