#include "io/child_process.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>
#include <sstream>

#include "isk/core/error.hpp"

#if defined(__unix__) || defined(__APPLE__)
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#if defined(__linux__)
#include <sys/prctl.h>
#endif
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#define ISK_HAVE_FORK 1
#endif

namespace isk::detail {
namespace {

std::string describeSeconds(double seconds) {
  std::ostringstream out;
  out << seconds << " s";
  return out.str();
}

std::string describeBytes(uint64_t bytes) {
  std::ostringstream out;
  out << bytes / (1024.0 * 1024.0) << " MiB";
  return out.str();
}

void checkLimits(const std::string& subject, const ChildLimits& limits) {
  if (!std::isfinite(limits.time_limit_seconds) ||
      limits.time_limit_seconds < 0) {
    throw Error(ErrorCode::kInvalidArgument,
                subject +
                    ": the import time limit must be a finite number of "
                    "seconds >= 0 (0: none), got " +
                    std::to_string(limits.time_limit_seconds));
  }
}

#if ISK_HAVE_FORK

// One message from the child: a type byte, a 64-bit payload length, the
// payload.
enum MessageType : uint8_t { kProgress = 1, kResult = 2, kFailure = 3 };
constexpr size_t kHeaderBytes = 1 + sizeof(uint64_t);

// --- child side -------------------------------------------------------------

bool writeAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

void send(int fd, MessageType type, const std::string& payload) {
  char header[kHeaderBytes];
  header[0] = static_cast<char>(type);
  const uint64_t length = payload.size();
  std::memcpy(header + 1, &length, sizeof(length));
  // The parent is gone or killed us: nothing is left to do.
  if (!writeAll(fd, header, sizeof(header)) ||
      !writeAll(fd, payload.data(), payload.size())) {
    ::_exit(3);
  }
}

// Set in the child when an allocation failed under the memory limit.
volatile bool g_allocation_failed = false;

// RLIMIT_AS caps the whole address space; the child starts as a copy of the
// application (and, under AddressSanitizer, with terabytes of reserved
// shadow), so the limit is set above what it already has.
void applyMemoryLimit(uint64_t extra_bytes) {
#if defined(__GLIBC__)
  // Memory the application freed but glibc kept would serve the import
  // without counting: give back what can be given back, and serve every
  // large block with its own mapping, which counts.
  ::malloc_trim(0);
  ::mallopt(M_MMAP_THRESHOLD, 256 * 1024);
#endif
  uint64_t current = 0;
#if defined(__linux__)
  if (FILE* statm = std::fopen("/proc/self/statm", "r")) {
    unsigned long long pages = 0;
    if (std::fscanf(statm, "%llu", &pages) == 1) {
      current = pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
    }
    std::fclose(statm);
  }
#endif
  rlimit limit{};
  ::getrlimit(RLIMIT_AS, &limit);
  const uint64_t wanted = current + extra_bytes;
  if (limit.rlim_max == RLIM_INFINITY || wanted < limit.rlim_max) {
    limit.rlim_cur = static_cast<rlim_t>(wanted);
    ::setrlimit(RLIMIT_AS, &limit);
  }
}

std::string failurePayload(ErrorCode code, int cl_status,
                           const std::string& message) {
  std::string payload(2 * sizeof(int32_t), '\0');
  const int32_t fields[2] = {static_cast<int32_t>(code), cl_status};
  std::memcpy(payload.data(), fields, sizeof(fields));
  return payload + message;
}

[[noreturn]] void childMain(
    int fd, pid_t parent, const std::string& subject, const ChildLimits& limits,
    const std::function<std::string(const ProgressSink&)>& work) {
  ::signal(SIGPIPE, SIG_IGN);
  // A crash ends the child at once and is told to the parent as its signal:
  // not the application's crash reporter (nor a sanitizer's) in a copy of
  // the application.
  for (int deadly : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) {
    ::signal(deadly, SIG_DFL);
  }
#if defined(__linux__)
  // Dies with the application, which may not live to kill it.
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
#endif
  if (::getppid() != parent) ::_exit(3);  // it died before we could know
  const bool memory_limited = limits.memory_limit_bytes > 0;
  if (memory_limited) {
    applyMemoryLimit(limits.memory_limit_bytes);
    // Parsers turn a failed allocation into errors of their own ("no
    // suitable reader found"): remember that one failed.
    std::set_new_handler([] {
      g_allocation_failed = true;
      std::set_new_handler(nullptr);
      throw std::bad_alloc();
    });
  }
  const std::string over_memory =
      subject + ": the import needed more memory than its limit of " +
      describeBytes(limits.memory_limit_bytes);
  std::string failure;
  try {
    std::string last_stage;
    float last_fraction = -1.f;
    const ProgressSink sink = [&](const char* stage, float fraction) {
      // A few hundred messages at most, whatever the parser's rate.
      if (stage == last_stage && fraction < 1.f &&
          fraction - last_fraction < 0.01f) {
        return;
      }
      last_stage = stage;
      last_fraction = fraction;
      std::string payload(sizeof(float), '\0');
      std::memcpy(payload.data(), &fraction, sizeof(float));
      send(fd, kProgress, payload + stage);
    };
    const std::string result = work(sink);
    send(fd, kResult, result);
    ::_exit(0);
  } catch (const Error& e) {
    const std::string message = e.what();
    // Assimp turns std::bad_alloc into an import error, sometimes with this
    // text.
    if (memory_limited && (g_allocation_failed ||
                           message.find("bad_alloc") != std::string::npos)) {
      const std::string prefix = subject + ": ";
      const std::string cause = message.compare(0, prefix.size(), prefix) == 0
                                    ? message.substr(prefix.size())
                                    : message;
      failure = failurePayload(ErrorCode::kLimitExceeded, 0,
                               over_memory + " (" + cause + ")");
    } else {
      failure = failurePayload(e.code(), e.clStatus(), message);
    }
  } catch (const std::bad_alloc&) {
    failure = memory_limited
                  ? failurePayload(ErrorCode::kLimitExceeded, 0, over_memory)
                  : failurePayload(ErrorCode::kMalformedAsset, 0,
                                   subject + ": the import ran out of memory");
  } catch (const std::exception& e) {
    failure = failurePayload(ErrorCode::kInternal, 0,
                             subject + ": the import threw " + e.what());
  } catch (...) {
    failure =
        failurePayload(ErrorCode::kInternal, 0,
                       subject + ": the import threw an unknown exception");
  }
  send(fd, kFailure, failure);
  ::_exit(0);
}

// --- parent side ------------------------------------------------------------

// Kills and reaps the child and closes the pipe unless the child was reaped
// already: no zombie and no stray process, whichever way the parent leaves.
class ChildGuard {
 public:
  ChildGuard(pid_t pid, int fd) : pid_(pid), fd_(fd) {}
  ~ChildGuard() {
    if (!reaped_) {
      ::kill(pid_, SIGKILL);
      reap();
    }
    ::close(fd_);
  }
  // Waits for the child; its wait status, or -1 when the application reaps
  // its children itself (SIGCHLD ignored: ECHILD).
  int reap() {
    int status = 0;
    pid_t r;
    do {
      r = ::waitpid(pid_, &status, 0);
    } while (r < 0 && errno == EINTR);
    reaped_ = true;
    return r == pid_ ? status : -1;
  }
  // True (and the status in *status) when the child has ended.
  bool ended(int* status) {
    pid_t r;
    do {
      r = ::waitpid(pid_, status, WNOHANG);
    } while (r < 0 && errno == EINTR);
    if (r == pid_ || (r < 0 && errno == ECHILD)) {
      if (r < 0) *status = -1;
      reaped_ = true;
      return true;
    }
    return false;
  }
  void killNow() { ::kill(pid_, SIGKILL); }
  int fd() const { return fd_; }

 private:
  pid_t pid_;
  int fd_;
  bool reaped_ = false;
};

std::string signalName(int signal) {
  switch (signal) {
    case SIGSEGV:
      return "SIGSEGV";
    case SIGABRT:
      return "SIGABRT";
    case SIGBUS:
      return "SIGBUS";
    case SIGFPE:
      return "SIGFPE";
    case SIGILL:
      return "SIGILL";
    case SIGKILL:
      return "SIGKILL";
    default:
      return "signal " + std::to_string(signal);
  }
}

#endif  // ISK_HAVE_FORK

}  // namespace

std::string runInChildProcess(
    const std::string& subject, const ChildLimits& limits,
    const std::function<std::string(const ProgressSink&)>& work,
    const ProgressSink& progress) {
  checkLimits(subject, limits);
#if !ISK_HAVE_FORK
  (void)work;
  (void)progress;
  throw Error(ErrorCode::kInvalidArgument,
              subject +
                  ": importing in a child process (a time or memory limit) "
                  "needs fork(), which this platform does not have");
#else
  int fds[2];
  if (::pipe(fds) != 0) {
    throw Error(ErrorCode::kIo, subject + ": no pipe for the import process: " +
                                    std::strerror(errno));
  }
  // Processes that other threads start with exec must not hold the pipe.
  ::fcntl(fds[0], F_SETFD, FD_CLOEXEC);
  ::fcntl(fds[1], F_SETFD, FD_CLOEXEC);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int error = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error(ErrorCode::kIo, subject +
                                    ": could not start the import process "
                                    "(fork: " +
                                    std::strerror(error) + ")");
  }
  if (pid == 0) {
    ::close(fds[0]);
    childMain(fds[1], parent, subject, limits, work);
  }
  ::close(fds[1]);
  ChildGuard child(pid, fds[0]);

  using Clock = std::chrono::steady_clock;
  const bool timed = limits.time_limit_seconds > 0;
  const auto deadline =
      Clock::now() +
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
          timed ? limits.time_limit_seconds : 0.0));
  std::string buffer;
  std::string result, failure;
  bool have_result = false, have_failure = false;
  int status = 0;
  bool ended = false;
  char chunk[1 << 16];
  for (bool open = true; open;) {
    // Polls in short slices: the pipe may stay open after the child died
    // (another thread forked meanwhile and holds its end), so the child's
    // state is checked between slices.
    int wait_ms = 200;
    if (timed) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                            deadline - Clock::now())
                            .count();
      if (left <= 0) {
        child.killNow();
        child.reap();
        throw Error(ErrorCode::kLimitExceeded,
                    subject +
                        ": the import did not finish within its time "
                        "limit of " +
                        describeSeconds(limits.time_limit_seconds) +
                        " and its process was stopped (some corrupt files "
                        "make Assimp's parsers loop forever)");
      }
      wait_ms = static_cast<int>(std::min<long long>(wait_ms, left));
    }
    pollfd poll_fd{child.fd(), POLLIN, 0};
    const int ready = ::poll(&poll_fd, 1, wait_ms);
    if (ready < 0 && errno != EINTR) {
      throw Error(ErrorCode::kIo, subject + ": poll on the import process: " +
                                      std::strerror(errno));
    }
    if (ready <= 0) {
      if (ended) break;  // ended earlier and nothing more came
      ended = child.ended(&status);
      continue;
    }
    const ssize_t n = ::read(child.fd(), chunk, sizeof(chunk));
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      break;
    }
    if (n == 0) {
      open = false;
    } else {
      buffer.append(chunk, static_cast<size_t>(n));
    }
    // Hands on every complete message.
    size_t at = 0;
    while (buffer.size() - at >= kHeaderBytes) {
      uint64_t length = 0;
      std::memcpy(&length, buffer.data() + at + 1, sizeof(length));
      if (buffer.size() - at - kHeaderBytes < length) break;
      const auto type = static_cast<MessageType>(buffer[at]);
      std::string payload = buffer.substr(at + kHeaderBytes, length);
      at += kHeaderBytes + length;
      if (type == kProgress && payload.size() >= sizeof(float)) {
        float fraction = 0;
        std::memcpy(&fraction, payload.data(), sizeof(float));
        if (progress) progress(payload.c_str() + sizeof(float), fraction);
      } else if (type == kResult) {
        result = std::move(payload);
        have_result = true;
      } else if (type == kFailure) {
        failure = std::move(payload);
        have_failure = true;
      }
    }
    buffer.erase(0, at);
  }
  if (!ended) status = child.reap();

  if (have_result) return result;
  if (have_failure && failure.size() >= 2 * sizeof(int32_t)) {
    int32_t fields[2];
    std::memcpy(fields, failure.data(), sizeof(fields));
    const bool known =
        fields[0] >= 0 &&
        fields[0] <= static_cast<int32_t>(ErrorCode::kLimitExceeded);
    throw Error(
        known ? static_cast<ErrorCode>(fields[0]) : ErrorCode::kInternal,
        failure.substr(sizeof(fields)), fields[1]);
  }
  if (status != -1 && WIFSIGNALED(status)) {
    const int signal = WTERMSIG(status);
    if (signal == SIGKILL) {
      throw Error(ErrorCode::kLimitExceeded,
                  subject +
                      ": the import process was killed (SIGKILL) before it "
                      "finished, most likely by the system's out-of-memory "
                      "killer");
    }
    throw Error(ErrorCode::kMalformedAsset,
                subject + ": the import crashed (" + signalName(signal) +
                    ") in its child process; the file is probably corrupt "
                    "(the application itself is unaffected)");
  }
  throw Error(
      ErrorCode::kInternal,
      subject + ": the import process ended without an answer" +
          (status != -1 && WIFEXITED(status)
               ? " (exit status " + std::to_string(WEXITSTATUS(status)) + ")"
               : std::string()));
#endif
}

}  // namespace isk::detail
