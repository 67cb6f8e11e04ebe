// The on-disk cache of operator tables (isk/fields/composition_operator.hpp): a
// cached table equals the bake bit for bit, a bad file is re-baked and
// rewritten, a disabled cache writes nothing, and nothing but the table's
// own file is ever replaced. Every test works in its own temporary folder.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "isk/fields/composition_operator.hpp"

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
  OperatorTableOrigin origin;
  OperatorTable table = loadOrBakeOperatorTable(
      op, kResolution, folder_.string(), 1, nullptr, &origin);
  EXPECT_EQ(origin, OperatorTableOrigin::kRebaked);
  EXPECT_TRUE(sameBits(table, baked));
  table = loadOrBakeOperatorTable(op, kResolution, folder_.string(), 1, nullptr,
                                  &origin);
  EXPECT_EQ(origin, OperatorTableOrigin::kLoaded);  // rewritten valid

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
  // A folder where the file would go: left alone, the table still comes.
  fs::create_directories(fileOf(op) / "keep");
  OperatorTableOrigin origin;
  const OperatorTable table = loadOrBakeOperatorTable(
      op, kResolution, folder_.string(), 1, nullptr, &origin);
  EXPECT_NE(origin, OperatorTableOrigin::kLoaded);
  EXPECT_TRUE(sameBits(table, bakeOperatorTable(op, kResolution, 1)));
  EXPECT_TRUE(fs::is_directory(fileOf(op) / "keep"));
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
  EXPECT_TRUE(
      sameBits(loadOrBakeOperatorTable(op, kResolution, blocked.string(), 1),
               bakeOperatorTable(op, kResolution, 1)));
}

}  // namespace
}  // namespace isk
