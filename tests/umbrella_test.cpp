// isk/isk.hpp: the whole public API of the isk library in one include, and
// none of isk::io's (the importer needs Assimp).
#include <gtest/gtest.h>

#include <type_traits>

#include "isk/isk.hpp"

namespace isk {
namespace {

TEST(Umbrella, OneIncludeReachesEveryStage) {
  // One type or function of each folder, in pipeline order.
  static_assert(std::is_class_v<Mesh>);                // core/
  static_assert(std::is_class_v<Skeleton>);            // rig/
  static_assert(std::is_class_v<CpuSkinning>);         // skinning/
  static_assert(std::is_class_v<ImplicitFields>);      // fields/
  static_assert(std::is_class_v<CpuSurfaceTracking>);  // tracking/
  static_assert(std::is_class_v<ClContext>);           // cl/
  static_assert(std::is_class_v<ImplicitSkinner>);     // the skinners
  static_assert(std::is_class_v<ImplicitCrowd>);
  const Rig rig = makeCylinderRig();  // tools/
  EXPECT_TRUE(rig.validate().isOk()) << rig.validate().reason();
  EXPECT_GT(rig.mesh.vertexCount(), 0);
}

}  // namespace
}  // namespace isk
