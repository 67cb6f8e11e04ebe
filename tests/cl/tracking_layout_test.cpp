// The tracking mesh laid out for the device (lib/src/cl/tracking_layout.hpp):
// host-only, checked against the mesh it comes from without a device.
#include "cl/tracking_layout.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include "test_support.hpp"
#include "tracking/tracking_tuning.hpp"

namespace isk {
namespace {

// Every property of the layout that the kernels rely on.
void checkLayout(const std::string& name,
                 const SurfaceTrackingOptions& options) {
  SCOPED_TRACE(name);
  const Rig& rig = test::rigNamed(name);
  const TrackingMesh mesh =
      TrackingMesh::build(rig.mesh, test::implicitFieldsOf(name));
  const detail::TrackingDeviceLayout layout =
      detail::trackingDeviceLayout(mesh, options);
  const int n = mesh.vertexCount();
  ASSERT_EQ(static_cast<int>(layout.order.size()), n);
  ASSERT_EQ(layout.march_count, mesh.trackedCount());
  // order and slot_of are inverse permutations; the tracked vertices come
  // first, in march order (or by index without it), the others by index.
  for (int k = 0; k < n; ++k) ASSERT_EQ(layout.slot_of[layout.order[k]], k);
  std::vector<int> tracked = mesh.march_order;
  if (!detail::tuningOf(options).march_order)
    std::sort(tracked.begin(), tracked.end());
  EXPECT_TRUE(std::equal(tracked.begin(), tracked.end(), layout.order.begin()));
  EXPECT_TRUE(std::is_sorted(layout.order.begin() + layout.march_count,
                             layout.order.end()));
  const TrackingLengths lengths = trackingLengths(mesh, options);
  for (int k = 0; k < n; ++k) {
    const int v = layout.order[k];
    ASSERT_EQ(layout.iso_values[k], mesh.iso_values[v]);
    ASSERT_EQ(layout.home_fields[k], mesh.home_field[v]);
    ASSERT_EQ(layout.representative[k],
              layout.slot_of[mesh.rings.representative[v]]);
    ASSERT_EQ(layout.finish_source[v],
              layout.slot_of[mesh.rings.representative[v]]);
    ASSERT_EQ(layout.rules[k], static_cast<uint8_t>(mesh.relaxation.rules[v]));
    ASSERT_EQ(layout.step_limits[2 * k], lengths.max_step[v]);
    ASSERT_EQ(layout.smoothing_radii[k], lengths.smoothing_radius[v]);
    // Row k is vertex v's ring, neighbours as device indices, and its near
    // row the neighbours within the smoothing radius, in ring order.
    const uint32_t begin = mesh.rings.offsets[v],
                   end = mesh.rings.offsets[v + 1];
    ASSERT_EQ(layout.ring_offsets[k + 1] - layout.ring_offsets[k], end - begin);
    std::vector<int> near;
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t j = layout.ring_offsets[k] + (i - begin);
      ASSERT_EQ(layout.ring_neighbours[j],
                layout.slot_of[mesh.rings.neighbours[i]]);
      ASSERT_EQ(layout.ring_weights[j], mesh.relaxation.weights[i]);
      if (mesh.ring_lengths[i] <= lengths.smoothing_radius[v])
        near.push_back(layout.ring_neighbours[j]);
    }
    ASSERT_TRUE(std::equal(
        near.begin(), near.end(),
        layout.near_neighbours.begin() + layout.near_offsets[k],
        layout.near_neighbours.begin() + layout.near_offsets[k + 1]));
  }
  // The reverse rows are the near rows transposed: w lists k exactly as
  // often as k's near row lists w.
  ASSERT_EQ(layout.reverse_neighbours.size(), layout.near_neighbours.size());
  for (int k = 0; k < n; ++k)
    for (uint32_t i = layout.near_offsets[k]; i < layout.near_offsets[k + 1];
         ++i) {
      const int w = layout.near_neighbours[i];
      const auto first =
          layout.reverse_neighbours.begin() + layout.reverse_offsets[w];
      const auto last =
          layout.reverse_neighbours.begin() + layout.reverse_offsets[w + 1];
      const auto listed = std::count(
          layout.near_neighbours.begin() + layout.near_offsets[k],
          layout.near_neighbours.begin() + layout.near_offsets[k + 1], w);
      ASSERT_EQ(std::count(first, last, k), listed)
          << "vertex " << w << " row " << k;
    }
}

TEST(TrackingDeviceLayout, FollowsTheMeshOnProceduralRigs) {
  for (const char* name : {"cylinder", "arm", "finger"}) {
    checkLayout(name, {});
    detail::TrackingTuning by_index;
    by_index.march_order = false;
    checkLayout(name, detail::withTuning({}, by_index));
  }
}

TEST(TrackingDeviceLayout, FollowsTheMeshOnAnAsset) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage(
        "the tracking layout of CesiumMan");
  checkLayout("CesiumMan.glb", {});
}

// The neighbourhoods' split: the option when set, else cells on a CPU
// device for a character with many tracked vertices per field only.
TEST(TrackingDeviceLayout, NeighbourhoodCellsFollowTheDeviceAndTheCharacter) {
  const std::string name = "arm";
  const TrackingMesh mesh = TrackingMesh::build(test::rigNamed(name).mesh,
                                                test::implicitFieldsOf(name));
  const bool many = mesh.march_order.size() >=
                    100 * static_cast<size_t>(std::max(mesh.field_count, 1));
  SurfaceTrackingOptions options;
  EXPECT_EQ(detail::neighbourhoodCellsPerAxis(mesh, options, true, 4),
            many ? 4 : 1);
  EXPECT_EQ(detail::neighbourhoodCellsPerAxis(mesh, options, false, 4), 1);
  detail::TrackingTuning seven;
  seven.neighbourhood_cells = 7;
  EXPECT_EQ(detail::neighbourhoodCellsPerAxis(
                mesh, detail::withTuning(options, seven), false, 4),
            7);
  TrackingMesh few = mesh;
  few.march_order.resize(std::min<size_t>(few.march_order.size(), 1));
  EXPECT_EQ(detail::neighbourhoodCellsPerAxis(few, {}, true, 4), 1);
}

}  // namespace
}  // namespace isk
