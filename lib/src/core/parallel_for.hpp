// Runs work(i) for i in [0, count) on a few threads (the library's offline
// builders: fitting, baking, operator tables).
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace isk::detail {

// `threads` <= 0: all hardware threads.
inline int threadCount(int threads) {
  return threads > 0 ? threads
                     : static_cast<int>(
                           std::max(1u, std::thread::hardware_concurrency()));
}

// Runs work(i) for i in [0, count) on `threads` threads; the calling thread
// reports progress(done / count) as items finish. The first exception thrown
// by an item is rethrown after all threads stop.
inline void parallelFor(int count, int threads,
                        const std::function<void(int)>& work,
                        const std::function<void(float)>& progress) {
  if (count <= 0) {
    if (progress) progress(1.f);
    return;
  }
  threads = std::max(1, std::min(threads, count));
  std::atomic<int> next{0};
  std::mutex mutex;
  std::condition_variable finished;
  int done = 0;
  std::exception_ptr failure;
  auto worker = [&] {
    for (;;) {
      const int i = next.fetch_add(1);
      if (i >= count) return;
      try {
        work(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!failure) failure = std::current_exception();
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        ++done;
      }
      finished.notify_one();
    }
  };
  if (progress) progress(0.f);
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  {
    std::unique_lock<std::mutex> lock(mutex);
    int reported = 0;
    while (done < count) {
      finished.wait(lock, [&] { return done != reported; });
      reported = done;
      if (progress) {
        lock.unlock();
        progress(static_cast<float>(reported) / count);
        lock.lock();
      }
    }
  }
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  if (progress) progress(1.f);
}

}  // namespace isk::detail
