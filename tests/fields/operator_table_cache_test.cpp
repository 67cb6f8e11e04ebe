// The on-disk cache of operator tables (isk/fields/composition_operator.hpp): a
// cached table equals the bake bit for bit, a bad file is re-baked and
// rewritten (with a warning, never a line on stderr), a disabled cache
// writes nothing, nothing but the table's own file is ever replaced, and the
// file's bytes are those earlier versions wrote. Every test works in its own
// temporary folder.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "isk/fields/composition_operator.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace fs = std::filesystem;

constexpr int kResolution = 17;  // small: the tests bake in milliseconds

class OperatorTableCache : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device random;
    folder_ = fs::temp_directory_path() /
              ("isk-operator-cache-test-" + std::to_string(random()));
    fs::remove_all(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  fs::path fileOf(CompositionOperator op) const {
    return folder_ / operatorTableCacheFileName(op, kResolution);
  }
  int filesInFolder() const {
    if (!fs::exists(folder_)) return 0;
    int n = 0;
    for ([[maybe_unused]] const auto& entry : fs::directory_iterator(folder_))
      ++n;
    return n;
  }

  fs::path folder_;
};

bool sameBits(const OperatorTable& a, const OperatorTable& b) {
  return a.op == b.op && a.resolution == b.resolution &&
         a.nodes.size() == b.nodes.size() &&
         std::memcmp(a.nodes.data(), b.nodes.data(),
                     a.nodes.size() * sizeof(float)) == 0;
}

TEST_F(OperatorTableCache, RoundTripEqualsTheBakeBitForBit) {
  for (CompositionOperator op :
       {CompositionOperator::kBlend, CompositionOperator::kBulge}) {
    const OperatorTable baked = bakeOperatorTable(op, kResolution, 1);
    OperatorTableOrigin origin;
    const OperatorTable first = loadOrBakeOperatorTable(
        op, kResolution, folder_.string(), 1, nullptr, &origin);
    EXPECT_EQ(origin, OperatorTableOrigin::kBaked);
    EXPECT_TRUE(fs::is_regular_file(fileOf(op)));
    const OperatorTable second = loadOrBakeOperatorTable(
        op, kResolution, folder_.string(), 1, nullptr, &origin);
    EXPECT_EQ(origin, OperatorTableOrigin::kLoaded);
    EXPECT_TRUE(sameBits(first, baked));
    EXPECT_TRUE(sameBits(second, baked));
  }
  // Two files, no temporary file left behind.
  EXPECT_EQ(filesInFolder(), 2);
  // The key holds the operator and the resolution.
  EXPECT_NE(operatorTableCacheFileName(CompositionOperator::kBlend, 128),
            operatorTableCacheFileName(CompositionOperator::kBulge, 128));
  EXPECT_NE(operatorTableCacheFileName(CompositionOperator::kBlend, 128),
            operatorTableCacheFileName(CompositionOperator::kBlend, 64));
}

TEST_F(OperatorTableCache, ACorruptOrTruncatedFileIsRebakedAndRewritten) {
  const CompositionOperator op = CompositionOperator::kBlend;
  const OperatorTable baked = bakeOperatorTable(op, kResolution, 1);
  ASSERT_TRUE(saveOperatorTable(baked, fileOf(op).string()));
  const auto size = fs::file_size(fileOf(op));

  // One flipped byte in the nodes: the checksum catches it.
  {
    std::fstream f(fileOf(op), std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(size / 2));
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x5a);
    f.seekp(static_cast<std::streamoff>(size / 2));
    f.write(&c, 1);
  }
  OperatorTable loaded;
  std::string why;
  EXPECT_FALSE(
      loadOperatorTable(fileOf(op).string(), op, kResolution, &loaded, &why));
  EXPECT_NE(why.find("checksum"), std::string::npos) << why;
  // Reported as a warning, not printed: the library never prints.
  OperatorTableOrigin origin;
  std::vector<std::string> warnings;
  ::testing::internal::CaptureStderr();
  OperatorTable table = loadOrBakeOperatorTable(
      op, kResolution, folder_.string(), 1, nullptr, &origin, &warnings);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(origin, OperatorTableOrigin::kRebaked);
  EXPECT_TRUE(sameBits(table, baked));
  EXPECT_EQ(warnings,
            std::vector<std::string>{"operator table cache unusable (" + why +
                                     "); baking the blend table again"});
  warnings.clear();
  table = loadOrBakeOperatorTable(op, kResolution, folder_.string(), 1, nullptr,
                                  &origin, &warnings);
  EXPECT_EQ(origin, OperatorTableOrigin::kLoaded);  // rewritten valid
  EXPECT_TRUE(warnings.empty());

  // Truncated, then garbage, then empty.
  for (const std::string& content :
       {std::string(100, 'x'), std::string("ISKOPTBL"), std::string()}) {
    {
      std::ofstream f(fileOf(op), std::ios::binary | std::ios::trunc);
      f << content;
    }
    table = loadOrBakeOperatorTable(op, kResolution, folder_.string(), 1,
                                    nullptr, &origin);
    EXPECT_EQ(origin, OperatorTableOrigin::kRebaked);
    EXPECT_TRUE(sameBits(table, baked));
    EXPECT_EQ(fs::file_size(fileOf(op)), size);
  }

  // A file of another table under this table's name: the key check.
  const OperatorTable bulge =
      bakeOperatorTable(CompositionOperator::kBulge, kResolution, 1);
  ASSERT_TRUE(saveOperatorTable(bulge, fileOf(op).string()));
  EXPECT_FALSE(
      loadOperatorTable(fileOf(op).string(), op, kResolution, &loaded, &why));
  table = loadOrBakeOperatorTable(op, kResolution, folder_.string(), 1, nullptr,
                                  &origin);
  EXPECT_EQ(origin, OperatorTableOrigin::kRebaked);
  EXPECT_TRUE(sameBits(table, baked));
}

TEST_F(OperatorTableCache, DisabledWritesNothing) {
  const char* saved = std::getenv("ISK_CACHE_DIR");
  const std::string saved_value = saved ? saved : "";
  ::setenv("ISK_CACHE_DIR", "off", 1);
  EXPECT_EQ(operatorTableCacheFolder(), "");
  ::setenv("ISK_CACHE_DIR", folder_.string().c_str(), 1);
  EXPECT_EQ(operatorTableCacheFolder(), folder_.string());
  if (saved)
    ::setenv("ISK_CACHE_DIR", saved_value.c_str(), 1);
  else
    ::unsetenv("ISK_CACHE_DIR");

  OperatorTableOrigin origin;
  const OperatorTable table = loadOrBakeOperatorTable(
      CompositionOperator::kBulge, kResolution, "", 1, nullptr, &origin);
  EXPECT_EQ(origin, OperatorTableOrigin::kBaked);
  EXPECT_TRUE(sameBits(
      table, bakeOperatorTable(CompositionOperator::kBulge, kResolution, 1)));
  EXPECT_FALSE(fs::exists(folder_));
}

TEST_F(OperatorTableCache, NeverReplacesAnythingElse) {
  const CompositionOperator op = CompositionOperator::kBulge;
  // A folder where the file would go: left alone, the table still comes,
  // and the two warnings say that it could neither be read nor written.
  fs::create_directories(fileOf(op) / "keep");
  OperatorTableOrigin origin;
  std::vector<std::string> warnings;
  const OperatorTable table = loadOrBakeOperatorTable(
      op, kResolution, folder_.string(), 1, nullptr, &origin, &warnings);
  EXPECT_NE(origin, OperatorTableOrigin::kLoaded);
  EXPECT_TRUE(sameBits(table, bakeOperatorTable(op, kResolution, 1)));
  EXPECT_TRUE(fs::is_directory(fileOf(op) / "keep"));
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_EQ(warnings[0].rfind("operator table cache unusable (", 0), 0u)
      << warnings[0];
  EXPECT_EQ(warnings[1],
            "could not write the operator table cache ('" +
                fileOf(op).string() +
                "' exists and is not a regular file); the table will be "
                "baked again next time");
  // Another file in the folder is untouched.
  { std::ofstream(folder_ / "notes.txt") << "mine"; }
  loadOrBakeOperatorTable(CompositionOperator::kBlend, kResolution,
                          folder_.string(), 1);
  std::ifstream notes(folder_ / "notes.txt");
  std::string text;
  notes >> text;
  EXPECT_EQ(text, "mine");
  // The folder can be below a file: the cache reports it, the bake works.
  const fs::path blocked = folder_ / "notes.txt" / "sub";
  warnings.clear();
  EXPECT_TRUE(
      sameBits(loadOrBakeOperatorTable(op, kResolution, blocked.string(), 1,
                                       nullptr, nullptr, &warnings),
               bakeOperatorTable(op, kResolution, 1)));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("could not write the operator table cache"),
            std::string::npos)
      << warnings[0];
}

// A table shared by the process hands the cache's warnings to the call
// that made it (later calls get the table made then, and no warning).
TEST_F(OperatorTableCache, SharedTableWarnsTheCallThatMadeIt) {
  fs::create_directories(folder_);
  { std::ofstream(folder_ / "file") << "mine"; }
  const test::ScopedEnv cache_dir("ISK_CACHE_DIR",
                                  (folder_ / "file" / "sub").c_str());
  const int resolution = 19;  // no other test of this process makes it
  std::vector<std::string> warnings;
  ::testing::internal::CaptureStderr();
  const auto table = sharedOperatorTable(CompositionOperator::kBulge,
                                         resolution, nullptr, &warnings);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].rfind("could not write the operator table cache (", 0),
            0u)
      << warnings[0];
  warnings.clear();
  EXPECT_EQ(sharedOperatorTable(CompositionOperator::kBulge, resolution,
                                nullptr, &warnings),
            table);
  EXPECT_TRUE(warnings.empty());
}

// The file's bytes, as every earlier version wrote them: existing caches
// keep loading. A 48-byte header (magic "ISKOPTBL", format version 1, the
// byte order mark 0x01020304, operator, resolution, the parameter hash of
// the file name, the float count, FNV-1a of the nodes' 32-bit words), then
// the nodes.
TEST_F(OperatorTableCache, TheFileLayoutIsUnchanged) {
  const CompositionOperator op = CompositionOperator::kBulge;
  const OperatorTable table = bakeOperatorTable(op, kResolution, 1);
  ASSERT_TRUE(saveOperatorTable(table, fileOf(op).string()));
  std::ifstream in(fileOf(op), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)),
                          std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.size(), 48 + table.bytes());
  auto u32 = [&](size_t at) {
    uint32_t v;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  auto u64 = [&](size_t at) {
    uint64_t v;
    std::memcpy(&v, bytes.data() + at, 8);
    return v;
  };
  EXPECT_EQ(bytes.substr(0, 8), "ISKOPTBL");
  EXPECT_EQ(u32(8), 1u);
  EXPECT_EQ(u32(12), 0x01020304u);
  EXPECT_EQ(u32(16), static_cast<uint32_t>(op));
  EXPECT_EQ(u32(20), static_cast<uint32_t>(kResolution));
  // "operator-table-v1-bulge-17-<16 hex digits of the hash>.bin"
  const std::string name = operatorTableCacheFileName(op, kResolution);
  ASSERT_EQ(name.rfind("operator-table-v1-bulge-17-", 0), 0u) << name;
  char hash[17];
  std::snprintf(hash, sizeof(hash), "%016llx",
                static_cast<unsigned long long>(u64(24)));
  EXPECT_EQ(name, "operator-table-v1-bulge-17-" + std::string(hash) + ".bin");
  EXPECT_EQ(u64(32), table.nodes.size());
  uint64_t checksum = 1469598103934665603ull;
  for (size_t i = 0; i < table.nodes.size(); ++i) {
    checksum ^= u32(48 + 4 * i);
    checksum *= 1099511628211ull;
  }
  EXPECT_EQ(u64(40), checksum);
  EXPECT_EQ(std::memcmp(bytes.data() + 48, table.nodes.data(), table.bytes()),
            0);
}

}  // namespace
}  // namespace isk
