#include "core/cache_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <random>

namespace isk::detail {
namespace {

namespace fs = std::filesystem;

std::string errnoText() { return std::strerror(errno); }

}  // namespace

uint64_t fnv1aWords(const void* data, size_t bytes, uint64_t hash) {
  const auto* p = static_cast<const unsigned char*>(data);
  const size_t words = bytes / 8;
  for (size_t i = 0; i < words; ++i) {
    uint64_t word;
    std::memcpy(&word, p + 8 * i, 8);
    hash ^= word;
    hash *= 1099511628211ull;
  }
  if (bytes % 8 != 0) {
    uint64_t word = 0;
    std::memcpy(&word, p + 8 * words, bytes % 8);
    hash ^= word;
    hash *= 1099511628211ull;
  }
  return hash;
}

bool writeFileAtomically(
    const std::string& path,
    const std::vector<std::pair<const void*, size_t>>& chunks,
    std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  const fs::path target(path);
  std::error_code ec;
  if (target.has_parent_path()) {
    fs::create_directories(target.parent_path(), ec);
    if (ec)
      return fail("cannot create folder '" + target.parent_path().string() +
                  "': " + ec.message());
  }
  // Only ever replace a regular file of our own name.
  const fs::file_status status = fs::symlink_status(target, ec);
  if (fs::exists(status) && !fs::is_regular_file(status))
    return fail("'" + path + "' exists and is not a regular file");

  // A fresh temporary file beside the target (O_EXCL: never an existing one).
  static std::atomic<unsigned> counter{0};
  std::random_device random;
  std::string temp;
  int fd = -1;
  for (int attempt = 0; attempt < 16 && fd < 0; ++attempt) {
    temp = path + ".tmp-" + std::to_string(::getpid()) + "-" +
           std::to_string(counter++) + "-" + std::to_string(random());
    fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd < 0 && errno != EEXIST)
      return fail("cannot create '" + temp + "': " + errnoText());
  }
  if (fd < 0)
    return fail("cannot create a temporary file beside '" + path + "'");
  auto write_all = [&](const void* data, size_t bytes) {
    const char* p = static_cast<const char*>(data);
    while (bytes > 0) {
      const ssize_t n = ::write(fd, p, bytes);
      if (n < 0) {
        if (errno == EINTR) continue;
        return false;
      }
      p += n;
      bytes -= static_cast<size_t>(n);
    }
    return true;
  };
  bool written = true;
  for (const auto& [data, bytes] : chunks)
    written = written && write_all(data, bytes);
  const std::string write_error = written ? "" : errnoText();
  const bool closed = ::close(fd) == 0;
  if (!written || !closed) {
    ::unlink(temp.c_str());
    return fail("cannot write '" + temp +
                "': " + (written ? errnoText() : write_error));
  }
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string why = errnoText();
    ::unlink(temp.c_str());
    return fail("cannot rename '" + temp + "' to '" + path + "': " + why);
  }
  return true;
}

}  // namespace isk::detail
