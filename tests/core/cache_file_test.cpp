// The library's one module for files on disk (lib/src/core/cache_file):
// the cache files' preamble and checksums, and the atomic write that every
// file the library writes goes through -- the final name holds the old file
// or the complete new one, never a partial one, and nothing but a regular
// file is ever replaced.
#include "core/cache_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace isk::detail {
namespace {

namespace fs = std::filesystem;
using test::ScopedTempDir;

constexpr CacheFileKind kTestKind = {{'I', 'S', 'K', 'T', 'E', 'S', 'T', '!'},
                                     3,
                                     "an isk test file",
                                     ChecksumWords::k64Bit};

std::string contentOf(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)),
                     std::istreambuf_iterator<char>());
}

std::vector<std::string> entriesOf(const fs::path& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// The hashes are in every cache file's name, key and checksum: they must
// never change.
TEST(CacheFile, HashesAreFnv1aFromTheFilesOffset) {
  EXPECT_EQ(kFnvOffset, 1469598103934665603ull);
  EXPECT_EQ(fnv1a("", 0), kFnvOffset);
  EXPECT_EQ(fnv1a("a", 1), (kFnvOffset ^ 'a') * 1099511628211ull);
  EXPECT_EQ(fnv1a("a", 1), 4953267810257967366ull);
  EXPECT_EQ(fnv1a("foobar", 6), 9870438755804841970ull);
  // From FNV's published basis, its published values.
  EXPECT_EQ(fnv1a("a", 1, 0xcbf29ce484222325ull), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(fnv1a("foobar", 6, 0xcbf29ce484222325ull), 0x85944171f73967e8ull);
  // Continuing a hash is hashing the concatenation.
  EXPECT_EQ(fnv1a("bar", 3, fnv1a("foo", 3)), fnv1a("foobar", 6));

  // Over words: each word is one step, a partial last word zero-padded.
  const uint32_t words32[3] = {1u, 0xdeadbeefu, 7u};
  uint64_t expected = kFnvOffset;
  for (const uint32_t w : words32) {
    expected ^= w;
    expected *= 1099511628211ull;
  }
  EXPECT_EQ(fnv1aWords32(words32, sizeof(words32)), expected);
  const uint64_t words64[2] = {0x0123456789abcdefull, 42ull};
  expected = kFnvOffset;
  for (const uint64_t w : words64) {
    expected ^= w;
    expected *= 1099511628211ull;
  }
  EXPECT_EQ(fnv1aWords(words64, sizeof(words64)), expected);
  const unsigned char tail[3] = {1, 2, 3};
  const uint64_t padded = 0x030201;  // little endian, as the tests run
  EXPECT_EQ(fnv1aWords(tail, 3), fnv1aWords(&padded, 8));

  EXPECT_EQ(hashText(0), "0000000000000000");
  EXPECT_EQ(hashText(0xaf63dc4c8601ec8cull), "af63dc4c8601ec8c");
}

TEST(CacheFile, PreambleIsMagicVersionAndByteOrder) {
  const CacheFilePreamble preamble = cacheFilePreamble(kTestKind);
  unsigned char bytes[16];
  std::memcpy(bytes, &preamble, 16);
  EXPECT_EQ(std::string(reinterpret_cast<char*>(bytes), 8), "ISKTEST!");
  uint32_t version = 0, order = 0;
  std::memcpy(&version, bytes + 8, 4);
  std::memcpy(&order, bytes + 12, 4);
  EXPECT_EQ(version, 3u);
  EXPECT_EQ(order, 0x01020304u);

  std::string why = "untouched";
  EXPECT_EQ(matchCacheFilePreamble(preamble, kTestKind, "f.bin", &why),
            PreambleMatch::kMatches);
  EXPECT_EQ(why, "untouched");

  CacheFilePreamble other = preamble;
  other.magic[7] = '?';
  EXPECT_EQ(matchCacheFilePreamble(other, kTestKind, "f.bin", &why),
            PreambleMatch::kOtherKind);
  EXPECT_EQ(why, "'f.bin' is not an isk test file");
  other = preamble;
  other.format_version = 2;
  EXPECT_EQ(matchCacheFilePreamble(other, kTestKind, "f.bin", &why),
            PreambleMatch::kOtherFormatVersion);
  EXPECT_EQ(why, "'f.bin' has format version 2, expected 3");
  other = preamble;
  other.byte_order = 0x04030201u;
  EXPECT_EQ(matchCacheFilePreamble(other, kTestKind, "f.bin", &why),
            PreambleMatch::kOtherByteOrder);
  EXPECT_EQ(why, "'f.bin' was written with another byte order");
  // The error is optional.
  EXPECT_EQ(matchCacheFilePreamble(other, kTestKind, "f.bin", nullptr),
            PreambleMatch::kOtherByteOrder);
}

TEST(CacheFile, ChecksumWordsFollowTheKind) {
  std::vector<float> payload(33);
  for (size_t i = 0; i < payload.size(); ++i) payload[i] = 0.25f * i - 3.f;
  const size_t bytes = payload.size() * sizeof(float);
  CacheFileKind words32 = kTestKind;
  words32.checksum_words = ChecksumWords::k32Bit;
  EXPECT_EQ(cacheFileChecksum(words32, payload.data(), bytes),
            fnv1aWords32(payload.data(), bytes));
  EXPECT_EQ(cacheFileChecksum(kTestKind, payload.data(), bytes),
            fnv1aWords(payload.data(), bytes));
  EXPECT_NE(cacheFileChecksum(words32, payload.data(), bytes),
            cacheFileChecksum(kTestKind, payload.data(), bytes));

  const uint64_t sum = cacheFileChecksum(kTestKind, payload.data(), bytes);
  std::string why;
  EXPECT_TRUE(checkCacheFileChecksum(kTestKind, payload.data(), bytes, sum,
                                     "f.bin", &why));
  EXPECT_TRUE(why.empty());
  payload[17] = 1e9f;
  EXPECT_FALSE(checkCacheFileChecksum(kTestKind, payload.data(), bytes, sum,
                                      "f.bin", &why));
  EXPECT_EQ(why, "'f.bin' fails its checksum (corrupt)");
}

TEST(AtomicFileWriter, WritesTheWholeFileOrNothing) {
  ScopedTempDir dir;
  const fs::path target = dir.path() / "data.bin";
  {
    AtomicFileWriter file(target.string(), ParentFolder::kMustExist);
    ASSERT_FALSE(file.failed()) << file.error();
    EXPECT_TRUE(file.write("hello, ", 7));
    // Until the commit, only the temporary file `<name>.tmp-<pid>` exists.
    EXPECT_FALSE(fs::exists(target));
    EXPECT_EQ(
        entriesOf(dir.path()),
        std::vector<std::string>{"data.bin.tmp-" + std::to_string(::getpid())});
    EXPECT_TRUE(file.write("world", 5));
    EXPECT_TRUE(file.commit());
    EXPECT_TRUE(file.commit());  // once committed, stays committed
  }
  EXPECT_EQ(contentOf(target), "hello, world");
  EXPECT_EQ(entriesOf(dir.path()), std::vector<std::string>{"data.bin"});

  // A writer dropped before its commit: the old file stays, whole.
  {
    AtomicFileWriter file(target.string(), ParentFolder::kMustExist);
    file.write("partial", 7);
  }
  EXPECT_EQ(contentOf(target), "hello, world");
  EXPECT_EQ(entriesOf(dir.path()), std::vector<std::string>{"data.bin"});

  // An existing regular file is replaced.
  std::string why;
  const std::string first = "abc", second = "defg";
  ASSERT_TRUE(writeFileAtomically(
      target.string(), {{first.data(), first.size()}, {second.data(), 4}},
      ParentFolder::kMustExist, &why))
      << why;
  EXPECT_EQ(contentOf(target), "abcdefg");
  ASSERT_TRUE(
      writeFileAtomically(target.string(), {}, ParentFolder::kMustExist, &why));
  EXPECT_EQ(contentOf(target), "");
  EXPECT_EQ(entriesOf(dir.path()), std::vector<std::string>{"data.bin"});
}

TEST(AtomicFileWriter, TheFolderIsCreatedOnlyWhenAsked) {
  ScopedTempDir dir;
  const fs::path nested = dir.path() / "a" / "b" / "data.bin";
  std::string why;
  EXPECT_FALSE(writeFileAtomically(nested.string(), {{"x", 1}},
                                   ParentFolder::kMustExist, &why));
  EXPECT_NE(why.find(nested.string()), std::string::npos) << why;
  EXPECT_FALSE(fs::exists(dir.path() / "a"));
  ASSERT_TRUE(writeFileAtomically(nested.string(), {{"x", 1}},
                                  ParentFolder::kCreate, &why))
      << why;
  EXPECT_EQ(contentOf(nested), "x");

  // A folder that cannot be made (a file in the way) is an error naming it.
  { std::ofstream(dir.path() / "file") << "mine"; }
  const fs::path blocked = dir.path() / "file" / "sub" / "data.bin";
  EXPECT_FALSE(writeFileAtomically(blocked.string(), {{"x", 1}},
                                   ParentFolder::kCreate, &why));
  EXPECT_NE(why.find("cannot create folder"), std::string::npos) << why;
  EXPECT_EQ(contentOf(dir.path() / "file"), "mine");
}

TEST(AtomicFileWriter, OnlyEverReplacesARegularFile) {
  ScopedTempDir dir;
  // A folder under the name: refused, left alone, no temporary file made.
  const fs::path folder = dir.path() / "taken";
  fs::create_directories(folder / "inside");
  AtomicFileWriter onto_folder(folder.string(), ParentFolder::kMustExist);
  EXPECT_TRUE(onto_folder.failed());
  EXPECT_EQ(onto_folder.error(),
            "'" + folder.string() + "' exists and is not a regular file");
  EXPECT_FALSE(onto_folder.write("x", 1));
  EXPECT_FALSE(onto_folder.commit());
  EXPECT_TRUE(fs::is_directory(folder / "inside"));
  EXPECT_EQ(entriesOf(dir.path()), std::vector<std::string>{"taken"});

  // A link under the name: neither the link nor what it points to changes.
  { std::ofstream(dir.path() / "pointed") << "mine"; }
  fs::create_symlink(dir.path() / "pointed", dir.path() / "link");
  std::string why;
  EXPECT_FALSE(writeFileAtomically((dir.path() / "link").string(), {{"x", 1}},
                                   ParentFolder::kMustExist, &why));
  EXPECT_NE(why.find("not a regular file"), std::string::npos) << why;
  EXPECT_TRUE(fs::is_symlink(dir.path() / "link"));
  EXPECT_EQ(contentOf(dir.path() / "pointed"), "mine");
  EXPECT_EQ(entriesOf(dir.path()),
            (std::vector<std::string>{"link", "pointed", "taken"}));
}

TEST(AtomicFileWriter, ATakenTemporaryNameIsLeftAloneAndAnotherUsed) {
  ScopedTempDir dir;
  const fs::path target = dir.path() / "data.bin";
  const std::string plain =
      target.string() + ".tmp-" + std::to_string(::getpid());
  // Another writer's temporary file (or a dead process's leftover).
  { std::ofstream(plain) << "someone else's"; }
  {
    AtomicFileWriter first(target.string(), ParentFolder::kMustExist);
    AtomicFileWriter second(target.string(), ParentFolder::kMustExist);
    ASSERT_FALSE(first.failed()) << first.error();
    ASSERT_FALSE(second.failed()) << second.error();
    EXPECT_EQ(entriesOf(dir.path()).size(), 3u);
    first.write("first", 5);
    second.write("second", 6);
    EXPECT_TRUE(first.commit());
    EXPECT_EQ(contentOf(target), "first");
    EXPECT_TRUE(second.commit());  // the last commit wins, whole
  }
  EXPECT_EQ(contentOf(target), "second");
  EXPECT_EQ(contentOf(plain), "someone else's");
  EXPECT_EQ(entriesOf(dir.path()).size(), 2u);
}

}  // namespace
}  // namespace isk::detail
