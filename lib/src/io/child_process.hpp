// Running a piece of work in a forked child process with a time and a memory
// limit, so that a third-party parser that loops forever, crashes or
// allocates without bound (Assimp on some corrupt files) ends with an
// isk::Error instead of taking the application down. POSIX only.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace isk::detail {

struct ChildLimits {
  // Seconds the child may run; past them it is killed (SIGKILL). 0: none.
  double time_limit_seconds = 0;
  // Bytes of address space the child may add to what it inherited from the
  // application (RLIMIT_AS). 0: none.
  uint64_t memory_limit_bytes = 0;
};

// Called with a stage name and a fraction in [0, 1].
using ProgressSink = std::function<void(const char* stage, float fraction)>;

// Forks; the child runs `work` (giving it a sink whose calls reach
// `progress` in the calling thread) and sends back the bytes it returns or
// the isk::Error it throws. Returns those bytes, or throws:
// - the child's isk::Error, code and message unchanged;
// - kLimitExceeded when the time limit passed (the child is killed) or the
//   child ran out of memory under a memory limit;
// - kMalformedAsset when the child died of a signal (a crash while reading
//   `subject`);
// - kInternal when it ended without an answer, kInvalidArgument for a
//   negative or non-finite limit, kIo when no process could be started.
// `subject` (the file) starts every message this function writes itself.
// The child never returns into the caller's code: it ends with _exit, so no
// destructor or atexit handler of the application runs twice.
std::string runInChildProcess(
    const std::string& subject, const ChildLimits& limits,
    const std::function<std::string(const ProgressSink&)>& work,
    const ProgressSink& progress);

}  // namespace isk::detail
