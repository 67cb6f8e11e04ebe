// The on-disk cache of implicit fields (isk/fields/field_cache.hpp): a second
// build loads bit-identical fields; a changed weight or vertex, a corrupt or a
// truncated file is detected and rebuilt, with a warning (never a line on
// stderr); ISK_CACHE_DIR=off disables it; the file's bytes are those
// earlier versions wrote.
// On the procedural arm and finger, and on CesiumMan when the data folder
// is there.
#include "isk/fields/field_cache.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace fs = std::filesystem;

template <typename T>
bool sameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() ||
          std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool sameVectors(const std::vector<Eigen::Vector3d>& a,
                 const std::vector<Eigen::Vector3d>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(a[i].data(), b[i].data(), 3 * sizeof(double)) != 0)
      return false;
  return true;
}

// The warnings of the build itself, without those of its cache.
std::vector<std::string> buildWarnings(const ImplicitFields& fields) {
  std::vector<std::string> kept;
  for (const std::string& w : fields.warnings)
    if (w.rfind("field cache unusable (", 0) != 0 &&
        w.rfind("could not write the field cache (", 0) != 0)
      kept.push_back(w);
  return kept;
}

bool hasWarning(const ImplicitFields& fields, const std::string& warning) {
  return std::find(fields.warnings.begin(), fields.warnings.end(), warning) !=
         fields.warnings.end();
}

// Every cached and derived part, bit for bit.
void expectIdentical(const ImplicitFields& a, const ImplicitFields& b) {
  ASSERT_EQ(a.fields.size(), b.fields.size());
  ASSERT_EQ(a.grids.fieldCount(), b.grids.fieldCount());
  EXPECT_EQ(a.grids.field_of_joint, b.grids.field_of_joint);
  EXPECT_EQ(a.grids.resolution, b.grids.resolution);
  for (size_t i = 0; i < a.fields.size(); ++i) {
    const std::string where = "field " + std::to_string(i);
    EXPECT_TRUE(sameVectors(a.samples[i].surface.positions,
                            b.samples[i].surface.positions))
        << where;
    EXPECT_TRUE(
        sameVectors(a.samples[i].closure.normals, b.samples[i].closure.normals))
        << where;
    EXPECT_EQ(a.samples[i].culled, b.samples[i].culled) << where;
    const Hrbf& ha = a.fields[i].hrbf;
    const Hrbf& hb = b.fields[i].hrbf;
    EXPECT_TRUE(sameBytes(ha.lambdas(), hb.lambdas())) << where;
    EXPECT_TRUE(sameVectors(ha.betas(), hb.betas())) << where;
    EXPECT_TRUE(sameVectors(ha.normalisedCentres(), hb.normalisedCentres()))
        << where;
    EXPECT_EQ(ha.scale(), hb.scale()) << where;
    EXPECT_EQ(ha.constant(), hb.constant()) << where;
    EXPECT_EQ(a.fields[i].radius, b.fields[i].radius) << where;
    EXPECT_EQ(a.fields[i].guard_radius, b.fields[i].guard_radius) << where;
    EXPECT_TRUE(a.fields[i].bone_to_model.matrix() ==
                b.fields[i].bone_to_model.matrix())
        << where;
    const FieldGrid& ga = a.grids.grids[i];
    const FieldGrid& gb = b.grids.grids[i];
    EXPECT_EQ(ga.joint, gb.joint) << where;
    EXPECT_TRUE(ga.bone_to_model.matrix() == gb.bone_to_model.matrix())
        << where;
    EXPECT_TRUE(ga.box_min == gb.box_min && ga.box_max == gb.box_max) << where;
    EXPECT_TRUE(sameBytes(ga.nodes, gb.nodes)) << where;
    // The analytic field evaluates the same.
    const Eigen::Vector3d p =
        a.fields[i].segment.start + Eigen::Vector3d(0.01, 0.02, 0.03);
    EXPECT_EQ(a.fields[i].value(p), b.fields[i].value(p)) << where;
  }
  EXPECT_TRUE(sameBytes(a.iso_values, b.iso_values));
  EXPECT_EQ(a.outside_vertices, b.outside_vertices);
  EXPECT_EQ(buildWarnings(a), buildWarnings(b));
  EXPECT_EQ(a.composition.pairs.size(), b.composition.pairs.size());
}

ImplicitFieldsOptions cachedIn(const test::ScopedTempDir& dir) {
  ImplicitFieldsOptions options;
  options.cache = true;
  options.cache_folder = dir.path().string();
  return options;
}

void checkRig(const std::string& name) {
  SCOPED_TRACE(name);
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed(name);
  const ImplicitFieldsOptions options = cachedIn(dir);
  const ImplicitFields uncached = buildImplicitFields(rig);
  EXPECT_EQ(uncached.cache_origin, FieldCacheOrigin::kOff);

  const ImplicitFields first = buildImplicitFields(rig, options);
  EXPECT_EQ(first.cache_origin, FieldCacheOrigin::kBuilt);
  ASSERT_TRUE(fs::is_regular_file(first.cache_file)) << first.cache_file;
  EXPECT_EQ(fs::path(first.cache_file).parent_path(), dir.path());
  expectIdentical(uncached, first);

  std::vector<std::string> stages;
  ImplicitFieldsOptions watched = options;
  watched.progress = [&](const char* stage, float) {
    if (stages.empty() || stages.back() != stage) stages.push_back(stage);
  };
  const ImplicitFields second = buildImplicitFields(rig, watched);
  EXPECT_EQ(second.cache_origin, FieldCacheOrigin::kLoaded);
  expectIdentical(first, second);
  // Loaded: no sampling, fitting or baking.
  EXPECT_NE(std::find(stages.begin(), stages.end(), "loading"), stages.end());
  EXPECT_EQ(std::find(stages.begin(), stages.end(), "fitting"), stages.end());

  // One weight changed (moved to the vertex's second influence, so the
  // sum stays 1): stale, rebuilt, and the rebuilt file is used next.
  Rig reweighted = rig;
  SkinWeights& w = reweighted.weights;
  int changed = -1;
  for (int v = 0; v < rig.mesh.vertexCount() && changed < 0; ++v)
    if (w.influenceCount(v) >= 2) changed = v;
  ASSERT_GE(changed, 0) << "no vertex with two influences";
  const float delta = 0.1f * w.weights[w.offsets[changed] + 1];
  w.weights[w.offsets[changed]] += delta;
  w.weights[w.offsets[changed] + 1] -= delta;
  // Said in a warning, never printed: the library never prints.
  ::testing::internal::CaptureStderr();
  const ImplicitFields rebuilt = buildImplicitFields(reweighted, options);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(rebuilt.cache_origin, FieldCacheOrigin::kRebuilt);
  EXPECT_NE(rebuilt.cache_note.find("skin weights changed"), std::string::npos)
      << rebuilt.cache_note;
  EXPECT_TRUE(hasWarning(rebuilt, "field cache unusable (" +
                                      rebuilt.cache_note +
                                      "); building the fields again"));
  // The file holds the build's warnings, not the cache's.
  const ImplicitFields reloaded = buildImplicitFields(reweighted, options);
  EXPECT_EQ(reloaded.cache_origin, FieldCacheOrigin::kLoaded);
  EXPECT_EQ(reloaded.warnings, buildWarnings(rebuilt));

  // One vertex moved: stale; the fields are those of the moved mesh.
  Rig moved = rig;
  moved.mesh.positions(moved.mesh.vertexCount() / 2, 0) += 1e-3f;
  const ImplicitFields remade = buildImplicitFields(moved, options);
  EXPECT_EQ(remade.cache_origin, FieldCacheOrigin::kRebuilt);
  EXPECT_NE(remade.cache_note.find("mesh changed"), std::string::npos)
      << remade.cache_note;
  expectIdentical(buildImplicitFields(moved), remade);

  // Back to the original rig: stale again (one file per source), rebuilt.
  EXPECT_EQ(buildImplicitFields(rig, options).cache_origin,
            FieldCacheOrigin::kRebuilt);

  // A flipped byte in the payload: corrupt, rebuilt, identical fields.
  {
    std::fstream file(first.cache_file,
                      std::ios::in | std::ios::out | std::ios::binary);
    const auto size = fs::file_size(first.cache_file);
    file.seekg(static_cast<std::streamoff>(size / 2));
    char c = 0;
    file.read(&c, 1);
    c = static_cast<char>(c ^ 0x5a);
    file.seekp(static_cast<std::streamoff>(size / 2));
    file.write(&c, 1);
  }
  const ImplicitFields repaired = buildImplicitFields(rig, options);
  EXPECT_EQ(repaired.cache_origin, FieldCacheOrigin::kRebuilt);
  EXPECT_NE(repaired.cache_note.find("checksum"), std::string::npos)
      << repaired.cache_note;
  EXPECT_TRUE(hasWarning(repaired, "field cache unusable (" +
                                       repaired.cache_note +
                                       "); building the fields again"));
  expectIdentical(uncached, repaired);

  // A truncated file: corrupt, rebuilt.
  fs::resize_file(first.cache_file, fs::file_size(first.cache_file) - 100);
  const ImplicitFields after_truncation = buildImplicitFields(rig, options);
  EXPECT_EQ(after_truncation.cache_origin, FieldCacheOrigin::kRebuilt);
  EXPECT_NE(after_truncation.cache_note.find("corrupt"), std::string::npos)
      << after_truncation.cache_note;
  EXPECT_EQ(buildImplicitFields(rig, options).cache_origin,
            FieldCacheOrigin::kLoaded);

  // Other parameters: another file, the first one untouched.
  ImplicitFieldsOptions finer = options;
  finer.grid_resolution = 24;
  const ImplicitFields other = buildImplicitFields(rig, finer);
  EXPECT_EQ(other.cache_origin, FieldCacheOrigin::kBuilt);
  EXPECT_NE(other.cache_file, first.cache_file);
  EXPECT_EQ(buildImplicitFields(rig, options).cache_origin,
            FieldCacheOrigin::kLoaded);

  // No temporary file left behind.
  for (const auto& entry : fs::directory_iterator(dir.path()))
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
        << entry.path();
}

TEST(FieldCacheTest, ProceduralRigsLoadIdenticalFieldsAndRebuildStaleOnes) {
  checkRig("arm");
  checkRig("finger");
}

TEST(FieldCacheTest, AssetLoadsIdenticalFieldsAndRebuildsStaleOnes) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the CesiumMan field cache");
  checkRig("CesiumMan.glb");
}

// A cache that cannot be written is a warning; the build is whole.
TEST(FieldCacheTest, AnUnwritableCacheIsAWarning) {
  test::ScopedTempDir dir;
  { std::ofstream(dir.path() / "file") << "mine"; }
  const Rig& rig = test::rigNamed("arm");
  ImplicitFieldsOptions options;
  options.cache = true;
  options.cache_folder = (dir.path() / "file" / "sub").string();
  ::testing::internal::CaptureStderr();
  const ImplicitFields fields = buildImplicitFields(rig, options);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(fields.cache_origin, FieldCacheOrigin::kBuilt);
  const auto warning = std::find_if(
      fields.warnings.begin(), fields.warnings.end(), [](const std::string& w) {
        return w.rfind("could not write the field cache (", 0) == 0;
      });
  ASSERT_NE(warning, fields.warnings.end());
  EXPECT_NE(warning->find("); the fields will be built again next time"),
            std::string::npos)
      << *warning;
  expectIdentical(buildImplicitFields(rig), fields);
}

// The file's bytes, as every earlier version wrote them: existing caches
// keep loading. A 64-byte header (magic "ISKFIELD", format version 1, the
// byte order mark 0x01020304, the hashes of the mesh, weights, skeleton and
// parameters, the payload's size and FNV-1a of its 64-bit words), then the
// payload, starting with the build's warnings.
TEST(FieldCacheTest, TheFileLayoutIsUnchanged) {
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed("finger");
  const ImplicitFields fields = buildImplicitFields(rig, cachedIn(dir));
  ASSERT_EQ(fields.cache_origin, FieldCacheOrigin::kBuilt);
  EXPECT_EQ(
      fs::path(fields.cache_file).filename().string().rfind("fields-v1-", 0),
      0u)
      << fields.cache_file;
  std::ifstream in(fields.cache_file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)),
                          std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 64u);
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
  EXPECT_EQ(bytes.substr(0, 8), "ISKFIELD");
  EXPECT_EQ(u32(8), 1u);
  EXPECT_EQ(u32(12), 0x01020304u);
  EXPECT_EQ(u64(48), bytes.size() - 64);
  uint64_t checksum = 1469598103934665603ull;
  const size_t payload = bytes.size() - 64;
  for (size_t at = 64; at < bytes.size(); at += 8) {
    uint64_t word = 0;
    std::memcpy(&word, bytes.data() + at,
                std::min<size_t>(8, payload - (at - 64)));
    checksum ^= word;
    checksum *= 1099511628211ull;
  }
  EXPECT_EQ(u64(56), checksum);
  EXPECT_EQ(u64(64), fields.warnings.size());
}

TEST(FieldCacheTest, IskCacheDirOffDisablesIt) {
  const char* old = std::getenv("ISK_CACHE_DIR");
  const std::string saved = old ? old : "";
  test::ScopedTempDir dir;
  ImplicitFieldsOptions options;
  options.cache = true;  // folder from the environment
  ::setenv("ISK_CACHE_DIR", "off", 1);
  const ImplicitFields off =
      buildImplicitFields(test::rigNamed("arm"), options);
  ::setenv("ISK_CACHE_DIR", dir.path().c_str(), 1);
  const ImplicitFields on = buildImplicitFields(test::rigNamed("arm"), options);
  if (old)
    ::setenv("ISK_CACHE_DIR", saved.c_str(), 1);
  else
    ::unsetenv("ISK_CACHE_DIR");
  EXPECT_EQ(off.cache_origin, FieldCacheOrigin::kOff);
  EXPECT_TRUE(off.cache_file.empty());
  EXPECT_EQ(on.cache_origin, FieldCacheOrigin::kBuilt);
  EXPECT_EQ(fs::path(on.cache_file).parent_path(), dir.path());
  // Samples edited by a callback are never cached.
  ImplicitFieldsOptions edited = cachedIn(dir);
  edited.edit_samples = [](std::vector<BoneSamples>&) {};
  EXPECT_EQ(buildImplicitFields(test::rigNamed("arm"), edited).cache_origin,
            FieldCacheOrigin::kOff);
}

TEST(FieldCacheTest, PerJointSamplesChangeTheKeyAndTheFit) {
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed("arm");
  ImplicitFieldsOptions options = cachedIn(dir);
  const ImplicitFields plain = buildImplicitFields(rig, options);
  const std::string joint =
      rig.skeleton.joints[plain.grids.grids[0].joint].name;
  options.joint_samples[joint] = 120;
  const ImplicitFields more = buildImplicitFields(rig, options);
  EXPECT_EQ(more.cache_origin, FieldCacheOrigin::kBuilt);
  EXPECT_NE(more.cache_file, plain.cache_file);
  EXPECT_GT(more.samples[0].surface.size(), plain.samples[0].surface.size());
  EXPECT_EQ(more.samples[1].surface.size(), plain.samples[1].surface.size());
  options.joint_samples = {{"no-such-joint", 10}};
  EXPECT_THROW(buildImplicitFields(rig, options), Error);
}

}  // namespace
}  // namespace isk
