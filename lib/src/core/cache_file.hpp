// The library's files on disk, in one place: the framing of the binary
// cache files (operator tables, implicit fields: their preamble of magic,
// format version and byte order, the FNV-1a hashes of their keys and the
// checksum of their payload) and the atomic write every file the library
// writes goes through (caches, exported frames, glTF, parameter files): a
// temporary file beside the target, renamed over it when complete, so that
// the final name never holds a partial file, and only ever replacing a
// regular file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace isk::detail {

// --- Hashes -----------------------------------------------------------------

// The start of every hash. A digit short of FNV's published offset basis
// (14695981039346656037), and kept so: every cache file's name, keys and
// checksum were made with it.
constexpr uint64_t kFnvOffset = 1469598103934665603ull;

// FNV-1a's step over bytes (xor, then times the FNV prime), continuing
// from `hash`.
inline uint64_t fnv1a(const void* data, size_t bytes,
                      uint64_t hash = kFnvOffset) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

// FNV-1a over 64-bit words (a trailing partial word is zero-padded): a fast
// hash of large arrays.
uint64_t fnv1aWords(const void* data, size_t bytes, uint64_t hash = kFnvOffset);

// FNV-1a over 32-bit words (a trailing partial word is zero-padded).
uint64_t fnv1aWords32(const void* data, size_t bytes,
                      uint64_t hash = kFnvOffset);

// `hash` as 16 lower-case hex digits: the keys in cache file names.
std::string hashText(uint64_t hash);

// --- Binary cache files -----------------------------------------------------
//
// A cache file is a header and a payload. The header starts with the
// 16-byte preamble below; each kind adds its own key fields (hashes, sizes)
// and the checksum of its payload. Everything is in the writer's byte
// order, which the preamble records: a file from a machine of the other
// order is refused, not swapped.

// Written as the host sees it: reads back the same only in the same order.
constexpr uint32_t kCacheByteOrderMark = 0x01020304u;

// The payload's checksum: FNV-1a over words of this size.
enum class ChecksumWords { k32Bit, k64Bit };

// What tells one kind of cache file from another.
struct CacheFileKind {
  char magic[8];            // "ISKOPTBL", "ISKFIELD" (no terminator)
  uint32_t format_version;  // bumped when the layout changes
  const char* description;  // "an isk operator table": the messages
  ChecksumWords checksum_words;
};

// The first 16 bytes of every cache file.
struct CacheFilePreamble {
  char magic[8];
  uint32_t format_version;
  uint32_t byte_order;  // kCacheByteOrderMark
};
static_assert(sizeof(CacheFilePreamble) == 16, "the preamble is 16 bytes");

// The preamble a file of `kind` is written with.
CacheFilePreamble cacheFilePreamble(const CacheFileKind& kind);

// How a file's preamble compares with the kind expected.
enum class PreambleMatch {
  kMatches,
  kOtherKind,           // another magic: not a file of this kind
  kOtherFormatVersion,  // this kind, another layout
  kOtherByteOrder,      // this kind, written by a machine of the other order
};

// Compares `preamble` (read from `path`) with `kind`; anything but kMatches
// sets *error naming the path: "'<path>' is not <description>", "... has
// format version 2, expected 1", "... was written with another byte order".
PreambleMatch matchCacheFilePreamble(const CacheFilePreamble& preamble,
                                     const CacheFileKind& kind,
                                     const std::string& path,
                                     std::string* error);

// The checksum of a payload of `kind`.
uint64_t cacheFileChecksum(const CacheFileKind& kind, const void* payload,
                           size_t bytes);

// Whether `payload` has the checksum `expected`; if not, *error says that
// `path` "fails its checksum (corrupt)".
bool checkCacheFileChecksum(const CacheFileKind& kind, const void* payload,
                            size_t bytes, uint64_t expected,
                            const std::string& path, std::string* error);

// --- Atomic writes ----------------------------------------------------------

// What a write does when the target's folder is missing.
enum class ParentFolder {
  kMustExist,  // fail (files a user names: frames, glTF, parameters)
  kCreate,     // create it and its parents (the caches' folder)
};

// A file written under a fresh temporary name beside `path` (created with
// O_EXCL: never an existing file) and renamed to `path` by commit(). Until
// then `path` is untouched; a writer destroyed uncommitted, or whose write
// or commit failed, removes its temporary file. Refuses a `path` that
// exists and is not a regular file (a folder, a link). The first failure is
// kept in error(), naming the file and errno's reason; later calls do
// nothing. Never throws for I/O.
class AtomicFileWriter {
 public:
  AtomicFileWriter(const std::string& path, ParentFolder parent);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  // Appends `bytes` bytes; false once anything has failed.
  bool write(const void* data, size_t bytes);
  // Closes the temporary file and renames it to the path; false with
  // error() when this or anything before it failed.
  bool commit();

  bool failed() const { return !error_.empty(); }
  const std::string& error() const { return error_; }

 private:
  void fail(const std::string& why);

  std::string path_;
  std::string temporary_path_;
  int fd_ = -1;
  bool committed_ = false;
  std::string error_;
};

// The concatenated `chunks` (pointer, size) written to `path` by an
// AtomicFileWriter. False with *error on failure; never throws.
bool writeFileAtomically(
    const std::string& path,
    const std::vector<std::pair<const void*, size_t>>& chunks,
    ParentFolder parent, std::string* error);

}  // namespace isk::detail
