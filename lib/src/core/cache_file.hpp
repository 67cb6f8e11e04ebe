// Shared machinery of the on-disk caches (operator tables, implicit
// fields): atomic writes and FNV-1a hashes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace isk::detail {

constexpr uint64_t kFnvOffset = 1469598103934665603ull;

// FNV-1a over bytes, continuing from `hash`.
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
// checksum of large payloads.
uint64_t fnv1aWords(const void* data, size_t bytes, uint64_t hash = kFnvOffset);

// Writes the concatenated `chunks` (pointer, size) to `path` through a
// fresh temporary file beside it (O_EXCL) and a rename, creating the parent
// folder; only ever replaces a regular file. False with *error on failure
// (the temporary file is then removed); never throws.
bool writeFileAtomically(
    const std::string& path,
    const std::vector<std::pair<const void*, size_t>>& chunks,
    std::string* error);

}  // namespace isk::detail
