#include "core/cache_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

namespace isk::detail {
namespace {

namespace fs = std::filesystem;

std::string errnoText() { return std::strerror(errno); }

template <typename Word>
uint64_t fnv1aOverWords(const void* data, size_t bytes, uint64_t hash) {
  const auto* p = static_cast<const unsigned char*>(data);
  const size_t words = bytes / sizeof(Word);
  for (size_t i = 0; i < words; ++i) {
    Word word;
    std::memcpy(&word, p + sizeof(Word) * i, sizeof(Word));
    hash ^= word;
    hash *= 1099511628211ull;
  }
  if (bytes % sizeof(Word) != 0) {
    Word word = 0;
    std::memcpy(&word, p + sizeof(Word) * words, bytes % sizeof(Word));
    hash ^= word;
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace

uint64_t fnv1aWords(const void* data, size_t bytes, uint64_t hash) {
  return fnv1aOverWords<uint64_t>(data, bytes, hash);
}

uint64_t fnv1aWords32(const void* data, size_t bytes, uint64_t hash) {
  return fnv1aOverWords<uint32_t>(data, bytes, hash);
}

std::string hashText(uint64_t hash) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx",
                static_cast<unsigned long long>(hash));
  return text;
}

CacheFilePreamble cacheFilePreamble(const CacheFileKind& kind) {
  CacheFilePreamble preamble{};
  std::memcpy(preamble.magic, kind.magic, sizeof(preamble.magic));
  preamble.format_version = kind.format_version;
  preamble.byte_order = kCacheByteOrderMark;
  return preamble;
}

PreambleMatch matchCacheFilePreamble(const CacheFilePreamble& preamble,
                                     const CacheFileKind& kind,
                                     const std::string& path,
                                     std::string* error) {
  auto mismatch = [&](PreambleMatch match, const std::string& why) {
    if (error) *error = "'" + path + "' " + why;
    return match;
  };
  if (std::memcmp(preamble.magic, kind.magic, sizeof(preamble.magic)) != 0)
    return mismatch(PreambleMatch::kOtherKind,
                    std::string("is not ") + kind.description);
  if (preamble.format_version != kind.format_version)
    return mismatch(PreambleMatch::kOtherFormatVersion,
                    "has format version " +
                        std::to_string(preamble.format_version) +
                        ", expected " + std::to_string(kind.format_version));
  if (preamble.byte_order != kCacheByteOrderMark)
    return mismatch(PreambleMatch::kOtherByteOrder,
                    "was written with another byte order");
  return PreambleMatch::kMatches;
}

uint64_t cacheFileChecksum(const CacheFileKind& kind, const void* payload,
                           size_t bytes) {
  return kind.checksum_words == ChecksumWords::k32Bit
             ? fnv1aWords32(payload, bytes)
             : fnv1aWords(payload, bytes);
}

bool checkCacheFileChecksum(const CacheFileKind& kind, const void* payload,
                            size_t bytes, uint64_t expected,
                            const std::string& path, std::string* error) {
  if (cacheFileChecksum(kind, payload, bytes) == expected) return true;
  if (error) *error = "'" + path + "' fails its checksum (corrupt)";
  return false;
}

AtomicFileWriter::AtomicFileWriter(const std::string& path, ParentFolder parent)
    : path_(path) {
  const fs::path target(path);
  std::error_code ec;
  if (parent == ParentFolder::kCreate && target.has_parent_path()) {
    fs::create_directories(target.parent_path(), ec);
    if (ec) {
      fail("cannot create folder '" + target.parent_path().string() +
           "': " + ec.message());
      return;
    }
  }
  // Only ever replace a regular file of our own name.
  const fs::file_status status = fs::symlink_status(target, ec);
  if (fs::exists(status) && !fs::is_regular_file(status)) {
    fail("'" + path + "' exists and is not a regular file");
    return;
  }
  // `<path>.tmp-<pid>` first: what a caller that cleans up after a killed
  // process recognises (isk-skin --overwrite). When that name is taken (by
  // another thread, or left by a dead process of the same pid), names made
  // unique by a counter and a random number.
  static std::atomic<unsigned> counter{0};
  const std::string plain = path + ".tmp-" + std::to_string(::getpid());
  for (int attempt = 0; attempt < 16 && fd_ < 0; ++attempt) {
    std::string candidate = plain;
    if (attempt > 0) {
      std::random_device random;
      candidate +=
          "-" + std::to_string(counter++) + "-" + std::to_string(random());
    }
    fd_ = ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC,
                 0666);
    if (fd_ >= 0) {
      temporary_path_ = candidate;
    } else if (errno != EEXIST) {
      fail("cannot create '" + candidate + "': " + errnoText());
      return;
    }
  }
  if (fd_ < 0) fail("cannot create a temporary file beside '" + path + "'");
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_ && !temporary_path_.empty())
    ::unlink(temporary_path_.c_str());
}

void AtomicFileWriter::fail(const std::string& why) {
  if (error_.empty()) error_ = why;
}

bool AtomicFileWriter::write(const void* data, size_t bytes) {
  if (failed() || fd_ < 0 || committed_) return false;
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd_, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write '" + temporary_path_ + "': " + errnoText());
      return false;
    }
    p += n;
    bytes -= static_cast<size_t>(n);
  }
  return true;
}

bool AtomicFileWriter::commit() {
  if (committed_) return true;
  if (fd_ >= 0) {
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0)
      fail("cannot write '" + temporary_path_ + "': " + errnoText());
  }
  if (failed()) return false;
  if (::rename(temporary_path_.c_str(), path_.c_str()) != 0) {
    fail("cannot rename '" + temporary_path_ + "' to '" + path_ +
         "': " + errnoText());
    return false;
  }
  committed_ = true;
  return true;
}

bool writeFileAtomically(
    const std::string& path,
    const std::vector<std::pair<const void*, size_t>>& chunks,
    ParentFolder parent, std::string* error) {
  AtomicFileWriter file(path, parent);
  for (const auto& [data, bytes] : chunks) file.write(data, bytes);
  if (file.commit()) return true;
  if (error) *error = file.error();
  return false;
}

}  // namespace isk::detail
