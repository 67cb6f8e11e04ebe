// Surface tracking (Vaillant et al. 2013, section 5), CPU reference: after
// geometric skinning, each vertex marches back to its rest iso value in the
// composed field by Newton steps (eq. 4), stops at a contact (a jump of the
// gradient's direction), is relaxed tangentially between steps (eq. 5, 6),
// and contact regions are smoothed at the end (eq. 7).
//
// Projection (eq. 4 with the sign fixed: f grows inward, so a vertex with
// f < iso moves along +grad f):
//   x <- x + sigma (iso - f(x)) grad f / |grad f|^2,   sigma = 0.35,
// the move capped at max_step (a fraction of the bounding-box diagonal). A
// step first compares the normalized gradient with the one of the vertex's
// previous step: an angle above contact_angle (55 degrees) stops the vertex
// (contact, it does not move). |f - iso| < tolerance (field units) stops it
// as converged; f = 0 (outside every support) or a vanishing gradient stops
// it as lost. A stopped vertex does no more work this frame.
// Relaxation (eq. 5, 6), after each `projection_steps` steps, moves each
// marching vertex towards the mean-value-weighted centroid of its one-ring,
// tangentially (in the plane normal to grad f where the vertex's last
// projection step sampled it, with that step's f: no new field sample):
//   x <- x + mu T(sum_j w_j x_j - x),  mu = max(0, 1 - (|f - iso| - 1)^4),
// with the rest pose's weights (isk/core/one_ring.hpp, RelaxationWeights).
// Skinned-ring relaxation (skinned_ring_relaxation, on by default; our
// addition, see docs/algorithm.md): the centroid is taken less the skinned
// ring's own offset from the vertex within the skinned tangent plane,
//   x <- x + mu T(sum_j w_j x_j - P(sum_j w_j s_j - s) - x),
// s the skinned positions and P the projection normal to the vertex's
// skinned normal. Where the weights do not reproduce the vertex in its rest
// tangent plane (clamped mean value weights, a non-manifold ring's uniform
// ones, the long thin triangles of a coarse mesh) eq. 5 would move it even
// at rest; with P(...) taken out, rest and every rigid motion of the ring
// are left where skinning put them within the skin's tangent plane (the
// ring's curvature, along the normal, moves the vertex as in eq. 5 where
// the field's gradient is tilted from the skin's normal).
// Smoothing (eq. 7): beta = 1 on contact vertices, 0 elsewhere; diffused
// `beta_diffusion` times over the one-ring (contact vertices stay at 1, the
// others take the mean of themselves and their neighbours); then
// `smoothing_steps` times x <- (1 - beta) x + beta centroid(one-ring).
// Both use only neighbours within smoothing_radius (rest distance) of the
// vertex. Crease vertices (see below) get a second weight gamma, diffused the
// same way (`crease_diffusion` times), and `crease_steps` tangential Laplacian
// steps: x <- x + (1 - beta) gamma T(centroid - x),
// T removing the component along the ring's normal, so that vertices piled
// in a crease spread out without the crease shrinking.
// Crease gate (crease_gate, on by default; our addition, see
// docs/algorithm.md): a crease vertex is a source of gamma only as far as
// the march distorted its ring from the skinned layout. Its source value is
// the largest of three ramps: the ring's vector area now over its skinned
// vector area (1 at 0.4 and below, 0 from 0.8 on: crushed); the shift of
// the near centroid from the vertex, now less skinned, within the ring's
// plane, over the near neighbours' mean rest length (0 at 0.2 and below, 1
// from 0.5 on: pushed out of its ring); and the largest stretch of a spoke
// beyond its skinned length, over its rest length (0 at 0.1 and below, 1
// from 0.3 on: a spike). Crease vertices keep at least their source value
// through the diffusion. A crease the march left in its skinned layout is
// not spread: the uniform centroid of an irregular ring is not its vertex,
// and the steps would strain the skin around it.
// Boundary, isolated and duplicate vertices are neither relaxed nor smoothed.
// Strain limit (our addition, see docs/algorithm.md): last, every tracked
// vertex's offset from its skinned position, d = x - s, is made to vary
// slowly across the mesh: `strain_limit_steps` Jacobi steps each pull the
// two ends of every ring edge whose offsets differ by more than
// strain_limit * rest length towards each other (half the excess each, over
// the vertex's ring size). An edge's length then differs
// from its skinned length by about strain_limit of its rest length at most:
// where the fields fit a coarse or thin part poorly, neighbours that marched
// to different places (spikes, fold-overs) are brought back together, while
// an offset that is smooth across the mesh (the contact surface of a
// well-fitted fold, the bulge) passes unchanged.
// Fold guard (fold_guard, on by default; our addition, see
// docs/algorithm.md): within the strain limit's steps, a triangle has folded
// over when its normal opposes both its skinned normal and its corners'
// skinned normals, unless skinning folded it itself (as in a deep bend's
// crease). Its fold weight ramps from 0 to 1 past those thresholds, and
// each vertex takes the largest weight within fold_rings rings. A ring edge
// takes a limit between strain_limit and fold_strain_limit by the larger
// weight of its ends (0 by default: offsets averaged across a fold), the
// weights found again every fold_check_steps steps. A contact surface keeps
// its sharp offsets, since it flattens the skin without turning it over;
// the fold-overs of a poorly fitted coarse mesh are smoothed out.
// Tilt guard (tilt_guard_degrees, 60 by default, 0: off; our addition, see
// docs/algorithm.md): with the fold guard, a triangle also weighs in when it
// turned more than tilt_guard_degrees from its skinned normal and from its
// corners' skinned normals (ramped as the fold test): its edges take a
// limit between strain_limit and tilt_strain_limit. The spikes and crumples
// of a poorly fitted part, which turn the skin steeply without folding it
// over, are evened out.
//
// Volume restoration (volume_restore, on by default; our addition, see
// docs/algorithm.md): after the smoothing, each closed connected component
// of the welded mesh whose volume fell below its rest volume gets some of
// it back. The vertices that converged to their iso value inward of their
// skinned position (along the skinned normal n), away from contacts (beta =
// 0) and outside parts dressed in clothes' layers, are moved back out along
// n by a common fraction lambda of their inward move, weighted by
// (1 - gamma):
//   x <- x + min(lambda, L) w n,  w = max(0, -(x - s).n) (1 - gamma) m,
//   lambda = clamp((V_rest - V) / sum(w A), 0, volume_restore),
// m the share of the vertex's one-ring that moves too (no shear against a
// contact's border), A a third of the rest area of the vertex's
// triangles, L the vertex's limit: volume_restore, or at most
// ISK_VOLUME_NEAR_LIMIT (1) near another connected component of the mesh
// (VolumeGroups::near_other: eyes, teeth, a mannequin's other pieces),
// where skin pushed out past skinning would press into it. The union's
// notches on the outside of bends go back towards the skinning's surface
// while the contacts stay. A component that the step took past its rest
// volume (the volume grows faster than linearly on a small or sharply
// curved part) is stepped back by the secant: lambda scaled by (V_rest -
// V) over the volume it gained. Components with holes (more than 1% of their
// vertices on a border) and meshes that enclose no volume are left alone.
// Contact bulge (contact_bulge, on by default; our addition, see
// docs/algorithm.md): where a component misses more volume than its inward
// moves can give back (V_rest - V > volume_restore sum(w A)), the flesh
// pressed at its contacts bulges beside them. A band b around the contact
// vertices (1 on them, falling linearly with the rest distance along the
// mesh to 0 at contact_bulge_radius of the diagonal, grown over
// contact_bulge_steps rings at most) weighs the converged vertices away
// from contacts and other components: u = b (1 - gamma) e, e the mean rest
// length of the vertex's ring edges, times its clearance c in [0, 1]: 1
// where the composed field probed out along n, contact_bulge_clearance
// times its largest push away, stays ISK_BULGE_CLEARANCE_WIDTH below its
// iso value, 0 where it reaches it (a part it faces within that reach:
// no push into it); the rest of the missing volume goes out along n by a
// common fraction of u:
//   x <- x + min(lambda, L) w n + min(kappa, contact_bulge) u n,
//   kappa = (V_rest - V - volume_restore sum(w A)) / sum(u A),
// both stepped back together by the secant.
// Volume restored again (restore_again_steps, on by default; our addition,
// see docs/algorithm.md): the strain limit runs after the restoration and
// evens out the offsets it pushed out against the contacts' and creases',
// which do not move, so it takes back part of the volume. The restoration
// then runs once more on what the limit left, without the contact bulge
// (the limit after it is too short to even out a pushed band), and the
// limit takes restore_again_steps more steps to even out that push.
//
// Contact by home field (home_contact, on by default; our addition, see
// docs/algorithm.md): each vertex has a home field, the field of the
// bone it was partitioned to. A vertex that geometric skinning pushed into
// another part (the largest other field o exceeds its home field h by more
// than at rest: o - h - margin > contact_entry, with f > iso, and o - margin
// reaches its part's surface value less contact_home_slack) marches instead
// to the contact surface between the two parts, by Newton steps on c = o - h -
// margin + contact_gap along grad(o - h), and stops there as a contact, or
// where grad(o - h) turns back between two of its steps: c has a minimum
// above 0 there (the surface is out of reach), about which Newton steps
// would flip direction at every step and leave the vertex anywhere. The
// paper's march would carry such a vertex out through the far side of the other
// part when skinning put it past that part's bone (deep folds, Figure 14(d)),
// and piles both parts' vertices on one surface at a crease; contact_gap (field
// units) leaves the two parts' sheets a hair apart instead of crossing. A field
// joined to the home field by a blend pair whose joint is turned by less than
// 90 degrees from its bind pose is not an "other" part: there the blend shapes
// the fold (a fillet, no contact); from 90 degrees on the blend is a union and
// the parts meet in contact. Bulge pairs keep the max's contact crease: always
// other parts. A vertex that converges onto another part's surface beyond its
// rest margin ends in a crease between parts (a concave union edge, where the
// march piles vertices from both sides): it is marked kCrease and smoothed
// tangentially.
// Dislocation guard (dislocation_guard, on by default; our addition, see
// isk/tracking/dislocation.hpp and docs/algorithm.md): at the start of a
// frame, the vertices whose weights blend two joints the skeleton does not
// link, and whose relative motion the pose makes a turn about a far axis or
// a slide, are left untracked: they keep their skinned position.
// Duplicates (seam copies, see one_ring.hpp) copy their representative's
// result; normals are area-weighted over the welded mesh where the rest
// normals agree (so seams do not show and hard edges stay hard).
//
// The OpenCL twin is isk::ClSurfaceTracking (isk/cl/surface_tracking.hpp):
// same stages, same formulas; tests compare them stage by stage.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "isk/core/mesh.hpp"
#include "isk/core/one_ring.hpp"
#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/field_grid.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/tracking/dislocation.hpp"

namespace isk {

namespace detail {
struct TrackingTuning;      // lib/src/tracking/tracking_tuning.hpp
struct TrackingTestAccess;  // lib/src/tracking/tracking_test_access.hpp
}  // namespace detail

// The parameters of tracking (above); the defaults are the paper's values
// where it gives one.
struct SurfaceTrackingOptions {
  // Rounds of (projection_steps projection steps, then one relaxation). The
  // paper relaxes after each pair of projection steps.
  int rounds = 8;
  int projection_steps = 2;
  // Eq. 4's step factor, (0, 1]. The paper's 0.35 is its compromise
  // between speed of convergence and accuracy: larger steps stop the
  // vertices sooner and a little farther from their iso values, and at 1
  // some jump the contact surface (docs/performance.md).
  float sigma = 0.35f;
  float contact_angle_degrees = 55.f;  // gradient jump that stops a vertex
  float tolerance = 1e-3f;             // field units: converged below it
  // Largest move of one projection step, fraction of the rest mesh's
  // bounding-box diagonal (Newton steps explode where the gradient is weak).
  float max_step = 0.02f;
  // |grad f| * diagonal below it: the gradient has vanished (lost).
  float min_gradient = 1e-3f;
  bool relaxation = true;  // eq. 5, 6
  // The skinned ring's in-plane offset taken out of the relaxation's
  // centroid (see above); false: eq. 5 as the paper writes it.
  bool skinned_ring_relaxation = true;
  // Contact by home field (see above) and the gap it leaves, field units.
  bool home_contact = true;
  float contact_gap = 0.05f;
  // How far (field units) another part's field must exceed the home field,
  // over the rest margin, before a vertex marches to the contact surface
  // (docs/algorithm.md measures it: raised, poorly fitted characters keep
  // their volume and well-fitted folds lose their contact).
  float contact_entry = 1e-3f;
  // A vertex starts that march only where the other part's field, less the
  // rest margin, reaches the vertex's part's surface value
  // (TrackingMesh::home_surface) minus this (field units): below it the two
  // fields overlap outside both surfaces, a poor fit's overlap, and the march
  // there would pull the skin in (docs/algorithm.md). 1: no such test.
  float contact_home_slack = 0.03f;
  // A vertex that would start that march while its own part's field is
  // below its part's surface value less this (field units) -- skin that
  // skinning carried out of its own part, a deep bend's -- stops where it
  // is: the march to the contact would pull it deep into the other part
  // and the paper's march send it out through the far side
  // (docs/algorithm.md). 1: no such test.
  float contact_home_reach = 0.1f;
  // Rest creases (TrackingMesh::rest_crease): a vertex that lies at rest on
  // the surface of a part the composition does not pair with its own (the
  // skeleton does not link the two bones) does not start the march to a
  // contact while the two joints have turned by less than this (degrees)
  // relative to each other from the bind pose: the crease between the two
  // surfaces shifts, and the vertex marches to its iso value as in the
  // paper instead of to the contact surface, which lies inside both parts
  // (docs/algorithm.md). 0: off.
  float rest_crease_degrees = 30.f;
  // Volume restoration (see above): the largest fraction of a vertex's
  // inward move from its skinned position given back, in [0, 3] (0: off;
  // above 1 a vertex may go past its skinned position, outward, where the
  // contacts took more volume than the inward moves hold; at most
  // ISK_VOLUME_NEAR_LIMIT near another component of the mesh;
  // docs/algorithm.md measures the default).
  float volume_restore = 3.f;
  // The contact bulge (see above): the largest push of a band vertex, in
  // its mean rest edge lengths, [0, 10] (0: off; docs/algorithm.md
  // measures the default); the band's
  // reach, a fraction of the diagonal (rest distance along the mesh), and the
  // rings it grows over at most (each step one ring; cost grows with them).
  float contact_bulge = 3.f;
  float contact_bulge_radius = 0.2f;
  int contact_bulge_steps = 16;
  // The contact bulge's clearance probe: a band vertex is pushed only where
  // the composed field this far out along its push (in largest pushes,
  // [0, 10]; 0: no probe) is below its iso value, fading to 0 as another
  // part's surface comes within that reach (no push into a part it faces).
  float contact_bulge_clearance = 2.f;
  // Two fields joined by a blend are not other parts for the contact by
  // home field while their joint is turned by less than this from its bind
  // pose (degrees): the blend shapes a fold that turns by less into a
  // fillet; from it on the two sides meet in contact (docs/algorithm.md).
  float blend_contact_degrees = 45.f;
  int beta_diffusion = 1;   // eq. 7: diffusion iterations of beta
  int smoothing_steps = 8;  // eq. 7: Laplacian steps
  // Localized: diffusion and Laplacian steps use only the neighbours within
  // this rest distance (fraction of the diagonal), so that the smoothed
  // region has one size whatever the mesh's resolution (on a coarse mesh,
  // a few rings would smooth whole limbs away).
  float smoothing_radius = 0.02f;
  // Creases (see above): diffusion iterations of gamma and tangential
  // Laplacian steps.
  int crease_diffusion = 5;
  int crease_steps = 10;
  // The crease gate (see above); false: every crease vertex is a source of
  // gamma = 1.
  bool crease_gate = true;
  // The dislocation guard (see above); false: every vertex with an iso
  // value marches.
  bool dislocation_guard = true;
  // The strain limit (see above): the largest difference of two neighbours'
  // offsets from skinning, as a fraction of their rest distance, and the
  // Jacobi steps that enforce it (0: no limit).
  float strain_limit = 2.f;
  int strain_limit_steps = 32;
  // The volume restored again (see above): the strain limit's steps after
  // the second restoration, [0, 1000] (0: no second restoration; none
  // either without the restoration or the strain limit).
  int restore_again_steps = 8;
  // The fold guard (see above): on or off, the strain limit around a folded
  // triangle, how many rings around its corners it reaches, and how many
  // steps apart the folds are found again.
  bool fold_guard = true;
  float fold_strain_limit = 0.f;
  int fold_rings = 2;
  int fold_check_steps = 4;
  // The tilt guard (see above), within the fold guard: the turn of a
  // triangle from its skinned normal past which it weighs in (degrees, 0:
  // off), and the strain limit around such a triangle.
  float tilt_guard_degrees = 60.f;
  float tilt_strain_limit = 0.8f;
  // History-dependent tracking (a `start` given to begin): the share of its
  // offset from the skinned position a vertex keeps when it starts from its
  // last result, x = s + history_keep (start - s), in [0, 1]: a contact
  // the pose no longer makes fades, and the skin comes back to rest.
  float history_keep = 0.5f;
  // Speed-only switches of the device's tracking and of the broad phase
  // (field neighbourhoods, march order, occupied cells, value bounds,
  // neighbourhood cells, lane tests, active vertices): the same frames
  // whichever way they are set. The benchmarks and tests set them
  // (lib/src/tracking/tracking_tuning.hpp); null: every switch on and the
  // device's choice of neighbourhood cells.
  std::shared_ptr<const detail::TrackingTuning> tuning;

  // Names the first bad parameter and its valid range.
  Validation validate() const;
};

// The tilt guard's threshold, the cosine of tilt_guard_degrees; and the
// fold weight a fully tilted triangle takes, so that its edges' limit,
// strain_limit + w (fold_strain_limit - strain_limit), is tilt_strain_limit
// (clamped between the two; 0 when the tilt or the fold guard is off).
float tiltGuardCosine(const SurfaceTrackingOptions& options);
float tiltGuardScale(const SurfaceTrackingOptions& options);

// Whether restoreVolumeAgain() does anything: restore_again_steps > 0 with
// both the volume restoration and the strain limit on.
bool restoresVolumeAgain(const SurfaceTrackingOptions& options);

// Per-vertex state of the march, kept between stages (on the device for
// ClSurfaceTracking).
enum class TrackState : uint8_t {
  kMarching = 0,   // still moving
  kConverged = 1,  // |f - iso| < tolerance
  kContact = 2,    // stopped at a gradient jump (contact surface)
  kLost = 3,       // left every support, or the gradient vanished
  kUntracked = 4,  // iso value 0 (outside every field) or a seam duplicate
  kCrease = 5,     // converged on another part's surface (home_contact)
};

// "marching", "converged", "contact", ... (the enumerator without its k).
const char* trackStateName(TrackState state);

// The static per-vertex data of tracking, built once per character.
struct TrackingMesh {
  // Partners per field of activePartners (more than that are treated as
  // other parts).
  static constexpr int kMaxPartners = 8;

  // A blend or bulge pair of the composition, for activePartners.
  struct PartnerPair {
    int field_a = -1, field_b = -1;  // field indices: parent, child
    int joint_a = -1, joint_b = -1;  // their joints (skeleton indices)
    bool blend = false;              // a blend pair (false: bulge)
  };

  OneRings rings;                 // welded one-rings of the rest mesh
  RelaxationWeights relaxation;   // eq. 5's weights over those rings
  std::vector<float> iso_values;  // #V, 0: untracked
  std::vector<int> home_field;    // #V: field of the vertex's bone, -1
  // #V: max(0, o - h) at the bind pose, o the largest other field (all of
  // them: partners may become other parts when their joint turns).
  std::vector<float> home_margin;
  // #V: the median rest iso value of the tracked vertices whose home field
  // is the vertex's (its part's surface value), 0 where it has none.
  std::vector<float> home_surface;
  std::vector<PartnerPair> partner_pairs;
  // Two fields the composition does not pair, meeting at a rest crease.
  struct CreasePair {
    int home_field = -1, other_field = -1;  // field indices
    int home_joint = -1, other_joint = -1;  // their joints
  };
  // The rest creases: a tracked vertex lies on one where the largest field
  // of another part than its own (other_field), one the composition does
  // not pair with its own, is within kRestCreaseReach of the vertex's iso
  // value at the bind pose -- the vertex is on both surfaces -- and the
  // vertex is in a volume group and not near another component
  // (VolumeGroups::near_other: eyes, a mannequin's pieces keep their
  // contacts). rest_crease: #V, an index into rest_crease_pairs, -1 none.
  static constexpr float kRestCreaseReach = 0.01f;
  std::vector<CreasePair> rest_crease_pairs;
  std::vector<int> rest_crease;
  int field_count = 0;
  // Rest length of each one-ring edge, aligned with rings.neighbours.
  std::vector<float> ring_lengths;
  TriangleMatrix triangles;  // #F by 3
  // Normals: per vertex the triangles of its welded group whose corner has
  // a rest normal within ~8 degrees of its own (hard edges stay hard).
  VertexTriangleAdjacency normal_adjacency;
  float diagonal = 0;  // rest bounding-box diagonal (the model's size)
  // #V, or empty: every vertex's `diagonal`. The tracking's lengths
  // (trackingLengths) follow the size of the vertex's own character: a
  // crowd of different characters (isk::ImplicitCrowd) gives each of its
  // vertices its character's diagonal.
  std::vector<float> vertex_diagonals;
  // The tracked vertices (iso value > 0, representatives) in the order the
  // projection kernel marches them: by home field, then along a Morton
  // curve of the rest positions (locality of the grid samples).
  std::vector<int> march_order;
  // The dislocation guard's candidates (isk/tracking/dislocation.hpp),
  // sorted by vertex; empty: no vertex is ever left untracked by it. Not
  // filled by build (it needs the rig's weights): the skinners set it.
  std::vector<DislocationCandidate> dislocation_candidates;

  // Volume restoration's groups (see above): the closed connected
  // components of the welded mesh that enclose a volume.
  struct VolumeGroups {
    // 3 per triangle, group by group: the corners' representatives, wound
    // outward (SurfaceOrientation). A group's volume is taken about its
    // first triangle's first corner.
    std::vector<int> corners;
    std::vector<int> triangle_offsets;  // #groups + 1, triangles
    std::vector<double> rest_volume;    // #groups, > 0
    // #V: the vertex's group; -1 for seam copies, layers of clothes
    // (bone_partition.hpp: they follow the skin) and vertices of no group.
    std::vector<int> vertex_group;
    // #V: a third of the rest area of its group's triangles around the
    // vertex (0 outside any group).
    std::vector<float> vertex_area;
    // #V: +1 where the vertex's rest normal points out of its group (the
    // side its triangles are wound to), -1 where it points in (normals
    // of a mesh wound inside out, or flipped): n times it is outward.
    std::vector<float> normal_sign;
    // #V: 1 where a vertex of another connected component of the welded
    // mesh (one with triangles) lies within 2% of the rest bounding-box
    // diagonal: its restoration is limited to ISK_VOLUME_NEAR_LIMIT.
    std::vector<uint8_t> near_other;
    int groupCount() const { return static_cast<int>(rest_volume.size()); }
  };
  VolumeGroups volume_groups;

  int vertexCount() const { return static_cast<int>(iso_values.size()); }
  // Vertex v's diagonal (vertex_diagonals[v], else diagonal).
  float diagonalOf(int v) const {
    return vertex_diagonals.empty() ? diagonal : vertex_diagonals[v];
  }
  // Vertices that march: representatives with an iso value > 0.
  int trackedCount() const;

  // Validates sizes (isk::Error kInvalidArgument) and builds the rings,
  // weights, welded normal adjacency, home fields and margins of `mesh`
  // (rest pose) from its implicit fields (isk/fields/implicit_fields.hpp: iso
  // values, partition, grids, composition).
  static TrackingMesh build(const Mesh& mesh, const ImplicitFields& fields);
};

// Per vertex, the lengths of tracking in model units, from the options'
// fractions of the vertex's diagonal (TrackingMesh::diagonalOf): the
// largest move of a projection step, the smallest |grad f| (the option over
// the diagonal; the option itself for a zero diagonal) and the smoothing
// radius. The CPU reference and the OpenCL path both take them from here.
struct TrackingLengths {
  std::vector<float> max_step;          // #V
  std::vector<float> min_gradient;      // #V
  std::vector<float> smoothing_radius;  // #V
  std::vector<float> bulge_reach;       // #V: contact_bulge_radius's length
};
TrackingLengths trackingLengths(const TrackingMesh& mesh,
                                const SurfaceTrackingOptions& options);

// Per field (#fields by kMaxPartners, -1 padded) the fields that are not
// other parts for the contact by home field at the pose `skinning`
// (#joints): those joined to it by a blend pair whose joint is turned by
// less than options.blend_contact_degrees from its bind pose
// (pairJointAngles).
std::vector<int> activePartners(const TrackingMesh& mesh,
                                const TransformList& skinning,
                                const SurfaceTrackingOptions& options);

// Leaves out of mesh->rest_crease the pairs whose crease the skin's weights
// blend: where more than kBlendedRestCrease of a pair's vertices are
// dislocation candidates (mesh->dislocation_candidates, weighted at least
// kDislocationMinWeight) of the pair's other joint, skinning already blends
// the two parts all along their crease (anim_test.x's tube over two
// chains), and there the march to a contact keeps its volume.
constexpr float kBlendedRestCrease = 0.9f;
void dropBlendedRestCreases(TrackingMesh* mesh);

// Per rest crease pair (TrackingMesh::rest_crease_pairs) at the pose
// `skinning` (#joints): 1 while its two joints have turned by less than
// options.rest_crease_degrees relative to each other from the bind pose
// (the crease shifts: the other part is no contact for the vertices on it),
// else 0.
std::vector<int> restCreaseShifts(const TrackingMesh& mesh,
                                  const TransformList& skinning,
                                  const SurfaceTrackingOptions& options);

// The exact broad phase of tracking at a pose. Per field h, the fields
// whose posed support box (a parallelepiped: the grid's box through the
// field's bone -> model transform) meets h's, h included, ascending, each
// tagged kPartner when it is h or one of h's `partners` (an activePartners
// list); and the indices of mesh.partner_pairs (the composition's blended
// pairs) both of whose fields are listed. A point in h's box lies outside
// the box of every field not listed, so a vertex whose home field is h
// samples only h's list while it is in h's box: the same composed field,
// bit for bit (same order, so unions tie the same way), for a fraction of
// the fields (human-addon: 53 fields).
struct FieldNeighbourhoods {
  static constexpr int kPartner = 1 << 16;  // entry = field | kPartner
  static constexpr int kFieldMask = kPartner - 1;
  std::vector<int> offsets;       // #fields + 1, into entries
  std::vector<int> entries;       // field index, | kPartner
  std::vector<int> pair_offsets;  // #fields + 1, into pairs
  std::vector<int> pairs;         // indices of mesh.partner_pairs
  // The finer broad phase of the OpenCL projection
  // (splitNeighbourhoodsIntoCells): each field h's support box cut into
  // K^3 equal cells (K = cells_per_axis), cell (i, j, k) at index
  // h * K^3 + i + K * (j + K * k) (i along the box's x); in
  // cell_entries[cell_offsets[c] .. cell_offsets[c + 1]] the entries of h's
  // list (same order, same flags) whose field can be non-zero somewhere in
  // cell c. Empty until split.
  int cells_per_axis = 0;
  std::vector<int> cell_offsets;  // #fields * K^3 + 1
  std::vector<int> cell_entries;
  // Mean number of fields listed per field.
  double meanListed() const;
};
// to_bone: #fields model -> bone transforms at the pose (fieldTransforms);
// partners: activePartners at the same pose (may be empty: none).
FieldNeighbourhoods fieldNeighbourhoods(
    const TrackingMesh& mesh, const FieldGridSet& grids,
    const std::vector<Eigen::Affine3f>& to_bone,
    const std::vector<int>& partners);

// Fills neighbourhoods' cell lists (see FieldNeighbourhoods), K =
// cells_per_axis (1 to 16) cells per axis of each box: a cell lists
// an entry when the field's occupied box (occupied_boxes, #fields, bone
// frame: occupiedBox, outside which the field is 0), posed through to_bone
// (#fields, as for fieldNeighbourhoods) and taken as an axis-aligned box
// in h's bone frame, meets the cell; both are grown by 1e-3 of their size
// so that rounding never drops a field. A point of h's box is then in
// every non-zero field's list of the cell that holds it, the cell the
// kernel finds from the point's node coordinates u in h's grid:
// min(floor(u * K / (resolution - 1)), K - 1) per axis. A transform that is
// not finite lists the field in every cell. Throws
// isk::Error(kInvalidArgument) when the sizes do not match the
// neighbourhoods' fields or K is out of range.
void splitNeighbourhoodsIntoCells(
    FieldNeighbourhoods& neighbourhoods, const FieldGridSet& grids,
    const std::vector<Eigen::Affine3f>& to_bone,
    const std::vector<Eigen::AlignedBox3f>& occupied_boxes, int cells_per_axis);

// Whether the posed support boxes of grids a and b (through their model ->
// bone transforms) meet, by separating axes; each box is first grown by
// `margin` of its size per side so that rounding never separates boxes
// that touch.
bool posedBoxesMeet(const FieldGrid& a, const Eigen::Affine3f& a_to_bone,
                    const FieldGrid& b, const Eigen::Affine3f& b_to_bone,
                    float margin = 1e-3f);

// A vertex's home field sample and the largest sample of the other parts'
// fields (not the home field, not its partners in `partners`, an
// activePartners list; null: none), from the #fields samples at a point
// (value, gradient; zero when none).
struct HomeSamples {
  Eigen::Vector4f home = Eigen::Vector4f::Zero();   // value, gradient
  Eigen::Vector4f other = Eigen::Vector4f::Zero();  // value, gradient
};
HomeSamples homeSamples(const TrackingMesh& mesh, const int* partners,
                        int vertex, const Eigen::Vector4f* per_field);
// The value of the other part's field (less the rest margin) below which
// vertex v does not start the march to a contact:
// home_surface[v] - options.contact_home_slack.
float homeFloor(const TrackingMesh& mesh, int vertex,
                const SurfaceTrackingOptions& options);
// The value of vertex v's own part's field below which a vertex that would
// start the march to a contact stops instead:
// home_surface[v] - options.contact_home_reach.
float homeMinimum(const TrackingMesh& mesh, int vertex,
                  const SurfaceTrackingOptions& options);

// One frame's per-vertex results and counts.
struct TrackingCounts {
  int marching = 0, converged = 0, contact = 0, lost = 0, untracked = 0,
      crease = 0;
};
// How many vertices are in each state.
TrackingCounts countStates(const std::vector<TrackState>& states);

// Milliseconds per stage of one frame (host wall time on the CPU, profiling
// events on OpenCL).
struct TrackingStageTimes {
  double projection_ms = 0;    // all projection steps
  double relaxation_ms = 0;    // all relaxation steps
  double smoothing_ms = 0;     // beta diffusion and Laplacian steps
  double volume_ms = 0;        // volume restoration
  double strain_limit_ms = 0;  // the strain limit's steps
  double normals_ms = 0;       // seam copies and normals
  // Sum of the stages.
  double total() const {
    return projection_ms + relaxation_ms + smoothing_ms + volume_ms +
           strain_limit_ms + normals_ms;
  }
};

// The fold guard's per-frame data of one triangle (see above): its skinned
// unit normal, the unit sum of its corners' skinned normals, and how far the
// skinned triangle does not oppose that sum, in [0, 1] (0: skinning folded
// it itself, or it is degenerate).
struct FoldFrame {
  Eigen::Vector3f skinned = Eigen::Vector3f::Zero();
  Eigen::Vector3f expected = Eigen::Vector3f::Zero();
  float allowance = 0.f;
};

// The CPU reference of a character's tracking. Keeps pointers to `fields`,
// `composition` (may be null: union of all fields) and `mesh`: they must
// outlive it.
class CpuSurfaceTracking {
 public:
  // Throws isk::Error(kInvalidArgument) for bad options (naming the option)
  // or a tracking mesh not built by TrackingMesh::build.
  CpuSurfaceTracking(const FieldGridSet& fields, const Composition* composition,
                     const TrackingMesh& mesh,
                     const SurfaceTrackingOptions& options = {});

  // Stage by stage (what run() chains; tests call them one at a time).
  // begin: the frame's pose (#joints skinning transforms) and the skinned
  // positions (#V by 3) and normals (fallback of the normals stage). The
  // vertices march from their skinned positions; given `start` (#V by 3;
  // history-dependent tracking, isk/tracking/tracking_history.hpp), those
  // that the last frame stopped at a contact or in a crease start from it
  // instead. The skinned positions stay the reference of the stages that
  // compare with skinning. Throws
  // isk::Error(kInvalidArgument) for sizes that do not match the mesh or a
  // pose shorter than the fields' joints. The other stages throw
  // isk::Error(kInvalidArgument) before the first begin().
  void begin(const TransformList& skinning, const Matrix3Xf& skinned_positions,
             const Matrix3Xf& skinned_normals,
             const Matrix3Xf* start = nullptr);
  void project(int steps);    // `steps` projection steps (eq. 4)
  void relax();               // one relaxation step (eq. 5, 6)
  void smooth();              // beta, its diffusion and the Laplacian steps
  void restoreVolume();       // volume restoration (after smooth())
  void limitStrain();         // the strain limit's steps, with the fold guard
  void restoreVolumeAgain();  // the restoration and restore_again_steps more
                              // steps of the limit (after limitStrain())
  void finish();              // seam copies and normals

  // The whole frame: begin, rounds x (project, relax), smooth,
  // restoreVolume, limitStrain, restoreVolumeAgain, finish.
  void run(const TransformList& skinning, const Matrix3Xf& skinned_positions,
           const Matrix3Xf& skinned_normals, const Matrix3Xf* start = nullptr);
  // After run(): the positions moved by `offset` (a skinner adds its pose's
  // anchor back, isk/rig/pose_anchor.hpp), timed with the normals.
  void translate(const Eigen::Vector3f& offset);

  // The working state: #V by 3 positions and normals (model space, normals
  // of unit length after finish()), #V states.
  const Matrix3Xf& positions() const { return positions_; }
  const Matrix3Xf& normals() const { return normals_; }
  const std::vector<TrackState>& states() const { return states_; }
  // Two per vertex: beta (contacts, eq. 7) and gamma (creases).
  const std::vector<float>& beta() const { return beta_; }
  // #V: gamma's source value of each crease vertex (the crease gate, 1
  // without it), 0 elsewhere (after smooth()).
  const std::vector<float>& creaseSources() const { return crease_sources_; }
  const Matrix4Xf& previousGradients() const { return prev_; }
  // #V by 4: the surface each vertex marches to as its last projection step
  // sampled it (signed distance f - iso, or the contact function c, then
  // the unit normal; zero before any step): the relaxation's tangent plane
  // and mu, so that relaxation samples no field.
  const Matrix4Xf& relaxFrames() const { return relax_frames_; }
  // #V in [0, 1]: the fold guard's weight of each vertex at its last check
  // (after limitStrain()): the largest fold weight of the triangles within
  // fold_rings rings of it (a tilted triangle's scaled by tiltGuardScale).
  const std::vector<float>& foldWeights() const { return fold_weights_; }
  // Volume restoration's last run (after restoreVolume(), or the second
  // one of restoreVolumeAgain()): lambda per group
  // (TrackingMesh::volume_groups) and each vertex's weight w (#V).
  const std::vector<float>& volumeFractions() const {
    return volume_fractions_;
  }
  const std::vector<float>& restoreWeights() const { return restore_weights_; }
  // The contact bulge's last run (after restoreVolume(); the second
  // restoration, restoreVolumeAgain()'s, has no bulge and leaves them):
  // kappa per group and each vertex's band b and weight u (#V); all 0 on a
  // frame where no group misses more volume than its inward moves give back
  // (the band and the probe are skipped).
  const std::vector<float>& bulgeFractions() const { return bulge_fractions_; }
  const std::vector<float>& bulgeBand() const { return bulge_band_; }
  const std::vector<float>& bulgeWeights() const { return bulge_weights_; }
  // How many triangles the fold guard's last check found folded over or,
  // with the tilt guard, tilted (a weight above 0).
  int foldedTriangleCount() const { return folded_triangles_; }
  // Milliseconds per stage of the last run().
  const TrackingStageTimes& lastTimes() const { return times_; }
  const SurfaceTrackingOptions& options() const { return options_; }

 private:
  // Replaces the working state (the tests, through
  // detail::TrackingTestAccess: both backends from the same input).
  friend struct detail::TrackingTestAccess;
  void setState(const Matrix3Xf& positions,
                const std::vector<TrackState>& states,
                const Matrix4Xf& prev_gradients,
                const Matrix4Xf* relax_frames = nullptr);

  const FieldGridSet* fields_;
  const Composition* composition_;
  const TrackingMesh* mesh_;
  SurfaceTrackingOptions options_;
  TransformList skinning_;
  TrackingLengths lengths_;
  Matrix3Xf positions_, scratch_, skinned_, fallback_normals_, normals_;
  std::vector<TrackState> states_;
  std::vector<int> partners_;           // activePartners of the frame's pose
  std::vector<int> crease_shifts_;      // restCreaseShifts of the frame's pose
  FieldNeighbourhoods neighbourhoods_;  // of the frame's pose
  // Whether vertex v, on a rest crease whose joints turned by less than
  // rest_crease_degrees, marches to its iso value instead of starting the
  // march to a contact (its own part's field at least homeMinimum: skin
  // carried out of its part still stops).
  bool onShiftingRestCrease(int v, const HomeSamples& home) const;
  // The composed field at x for vertex v (its neighbourhood's fields when x
  // is in its home field's box); per_field: #fields samples, 0 where
  // not sampled.
  // home (when not null) receives homeSamples with the frame's partners.
  Eigen::Vector4f sampleAt(const ComposedFieldSampler& sampler, int v,
                           const Eigen::Vector3f& x, Eigen::Vector4f* per_field,
                           HomeSamples* home) const;
  // Throws isk::Error(kInvalidArgument) naming `stage` before begin().
  void checkBegun(const char* stage) const;
  Matrix4Xf prev_;          // previous unit gradient, w = 1 when set
  Matrix4Xf relax_frames_;  // see relaxFrames()
  std::vector<float> beta_, beta_scratch_, crease_sources_;
  // The fold guard: the frame's triangle frames (fold_frames_, from the
  // skinned positions and normals), then the weights (fold_weights_) from
  // the offsets (#V by 3).
  void limitStrainSteps(int steps);  // limitStrain() with `steps` steps
  void restoreVolumeWith(bool contact_bulge);  // restoreVolume()'s work
  void frameFolds();
  void weighFolds(const Matrix3Xf& offsets);
  std::vector<FoldFrame> fold_frames_;
  std::vector<float> volume_fractions_, restore_weights_;
  std::vector<float> bulge_fractions_, bulge_band_, bulge_weights_;
  std::vector<float> fold_weights_, fold_scratch_;
  int folded_triangles_ = 0;
  TrackingStageTimes times_;
  bool begun_ = false;  // a frame's state exists (begin() was called)
};

}  // namespace isk
