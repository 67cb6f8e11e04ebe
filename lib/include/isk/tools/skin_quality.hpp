// Quality measures of skinned frames against the rest pose and against dual
// quaternion skinning of the same pose: what "looks right" means for a
// deformation, measured rather than assumed (docs/testing.md, QUALITY.md).
//
// The paper's promises (Vaillant et al. 2013, Fig. 1, sections 4.2 and 5):
// volume kept at joints, interpenetration turned into contact, the rigid
// look of the skinning away from the fold. Per frame:
//   - self-intersecting triangle pairs of the welded mesh, fold-overs of
//     adjacent triangles included (isk/tools/self_intersection.hpp), and
//     those of them that are new against the rest pose;
//   - enclosed volume over the rest volume, and the covered volume (the
//     points enclosed once or more: overlaps counted once) over its rest
//     value;
//   - edge strain, |length / rest length - 1| over the welded edges;
//   - crumpled edges: welded edges between two triangles whose bending
//     angle changed from rest by more than crumple_degrees (the crumples
//     and spikes that a mean strain averages away);
//   - distance from the DQS frame of the same pose of the vertices away
//     from any contact, over the rest bounding-box diagonal;
//   - temporal jitter: the second difference of each vertex's positions
//     over three frames minus that of its DQS positions, over the diagonal;
//   - lost vertices (the tracking's, given by the caller);
//   - optionally, per part of the mesh (a bone's part: BonePartition's
//     vertex_joint), the edge strain against DQS's, the largest distance
//     from DQS, the new intersecting pairs and the crumpled edges against
//     DQS's: where on the character a deformation departs from skinning.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "isk/core/mesh.hpp"
#include "isk/core/types.hpp"

namespace isk {

struct SkinQualityOptions {
  // A vertex is near a contact when its DQS position lies within this
  // fraction of the rest diagonal of a contact seed: a vertex the caller
  // flags (stopped at a contact by the tracking) or a corner of a triangle
  // that the DQS frame makes intersect anew.
  float contact_radius = 0.05f;
  // An edge is crumpled when its bending angle (the signed angle between
  // its two triangles' planes, 0 where they are flat) differs from its rest
  // angle by more than this, in degrees.
  float crumple_degrees = 60.0f;
  // Optional, #V (or empty: no per-part measures): the part of each vertex,
  // a non-negative id (a joint index: BonePartition::vertex_joint) or -1
  // for none. Each frame then measures every part (FrameQuality::parts).
  std::vector<int> vertex_parts;
};

// One part's measures (SkinQualityOptions::vertex_parts): of a frame, or
// over a clip (summarizeQuality: means over the frames, the largest
// distance).
struct PartQuality {
  int part = -1;
  int edges = 0;  // welded edges with an end in the part (counted once)
  double edge_strain_mean = 0;      // the frame's, over those edges
  double dqs_edge_strain_mean = 0;  // the DQS frame's, same edges
  // Largest distance of the part's vertices from their DQS positions
  // (contacts included), over the rest diagonal.
  double dqs_distance_max = 0;
  // The frame's new self-intersecting pairs (not at rest) with a corner of
  // either triangle in the part (a pair counts once in each part it
  // touches), and the DQS frame's; over a clip, their sums.
  long long new_pairs = 0, dqs_new_pairs = 0;
  // The frame's crumpled edges with an end in the part, and the DQS
  // frame's; over a clip, their sums.
  long long crumpled_edges = 0, dqs_crumpled_edges = 0;
};

struct FrameQuality {
  int self_intersections = 0;      // every intersecting pair of the frame
  int new_self_intersections = 0;  // those not intersecting at rest
  // Unset when the rest mesh encloses about no volume (open or flat).
  std::optional<double> volume_ratio;
  // coveredVolume (isk/tools/mesh_metrics.hpp) over the rest pose's; unset
  // where volume_ratio is.
  std::optional<double> covered_volume_ratio;
  double edge_strain_mean = 0, edge_strain_max = 0;
  // Welded edges of two triangles whose bending angle changed from rest by
  // more than SkinQualityOptions::crumple_degrees.
  int crumpled_edges = 0;
  // Vertices (welded) near a contact, and the others' distance from their
  // DQS position over the diagonal (0 without a DQS frame: the frame is one).
  int contact_region_vertices = 0;
  double dqs_distance_mean = 0, dqs_distance_max = 0;
  // Unset for the first two frames.
  std::optional<double> jitter_mean, jitter_max;
  int lost_vertices = 0;
  // With SkinQualityOptions::vertex_parts: each part with an edge, by
  // ascending id (without a DQS frame, DQS's figures are the frame's own).
  std::vector<PartQuality> parts;
};

// The measures summed up over a clip.
struct QualitySummary {
  int frames = 0;
  int self_intersections_max = 0;
  int new_self_intersections_max = 0;
  long long new_self_intersections_total = 0;
  std::optional<double> volume_ratio_min, volume_ratio_max;
  std::optional<double> covered_volume_ratio_min, covered_volume_ratio_max;
  double edge_strain_mean = 0;  // mean over the frames of their means
  double edge_strain_max = 0;
  int crumpled_edges_max = 0;
  long long crumpled_edges_total = 0;
  double dqs_distance_max = 0;
  std::optional<double> jitter_max;
  int lost_vertices_max = 0;
  // The frame with the most new intersecting pairs; on a tie (or none),
  // the one whose volume is furthest from the rest volume; then the first.
  int worst_frame = -1;
  // Per part (the frames' parts): mean over the frames of the strains, the
  // largest distance, the sums of the new pairs; by ascending id.
  std::vector<PartQuality> parts;
};

QualitySummary summarizeQuality(const std::vector<FrameQuality>& frames);

// Measures the frames of one clip of one mesh in frame order (the jitter
// needs the two frames before).
class SkinQuality {
 public:
  // `rest` the rest mesh; `vertex_groups` (#V, group ids that are vertex
  // indices: isk::coincidentVertexGroups or a tracking mesh's
  // representatives) weld seam duplicates. Counts the rest pose's
  // intersecting pairs. Throws isk::Error(kInvalidArgument) on a bad size
  // (of the groups or of options.vertex_parts, or a part id below -1) or a
  // crumple_degrees outside (0, 180].
  SkinQuality(const Mesh& rest, std::vector<int> vertex_groups,
              SkinQualityOptions options = {});

  // The next frame: `positions` #V by 3; `dqs` the DQS frame of the same
  // pose (nullptr: `positions` is that frame); `contacts` #V flags of the
  // vertices stopped at a contact (nullptr: none); `lost` the tracking's
  // lost vertices. Throws isk::Error(kInvalidArgument) on bad sizes.
  FrameQuality measure(const Matrix3Xf& positions, const Matrix3Xf* dqs,
                       const std::vector<uint8_t>* contacts = nullptr,
                       int lost = 0);

  // Intersecting pairs of the rest pose, sorted.
  const std::vector<std::pair<int, int>>& restPairs() const {
    return rest_pairs_;
  }
  // The pairs of the last measured frame, sorted.
  const std::vector<std::pair<int, int>>& lastPairs() const {
    return last_pairs_;
  }
  // The pairs of the last frame that are new against the rest pose.
  const std::vector<std::pair<int, int>>& lastNewPairs() const {
    return last_new_pairs_;
  }
  float diagonal() const { return diagonal_; }
  double restVolume() const { return rest_volume_; }

 private:
  // Per hinge (hinges_): whether its bending angle in `positions` changed
  // from rest by more than crumple_degrees.
  std::vector<uint8_t> crumpledHinges(const Matrix3Xf& positions) const;

  // Vertices near a contact of the frame (flags, #V).
  std::vector<uint8_t> contactRegion(
      const Matrix3Xf& reference, const std::vector<uint8_t>* contacts,
      const std::vector<std::pair<int, int>>& reference_new_pairs) const;

  TriangleMatrix triangles_;
  std::vector<int> groups_;
  SkinQualityOptions options_;
  std::vector<std::pair<int, int>> rest_pairs_, last_pairs_, last_new_pairs_;
  std::vector<std::pair<int, int>> edges_;  // welded, unique
  std::vector<float> edge_rest_lengths_;
  // The welded edges that two triangles share and no other, each as its
  // two ends and the two opposite corners, with its rest bending angle
  // (radians): the crumpled edges' measure.
  std::vector<std::array<int, 4>> hinges_;
  std::vector<float> hinge_rest_angles_;
  // Per part with an edge (ascending id): the edges with an end in it.
  std::vector<int> part_ids_;
  std::vector<std::vector<int>> part_edges_;
  double rest_volume_ = 0, rest_covered_volume_ = 0;
  bool volume_meaningful_ = false;
  float diagonal_ = 0;
  // The two frames before (and their DQS frames), for the jitter.
  std::vector<Matrix3Xf> history_, dqs_history_;
};

}  // namespace isk
