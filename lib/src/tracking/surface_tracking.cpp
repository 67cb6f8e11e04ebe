#include "isk/tracking/surface_tracking.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <string>

#include "abi.h"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/core/surface_orientation.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "tracking/tracking_tuning.hpp"
#include "usability.hpp"

namespace isk {

namespace {

// Rest normals closer than this share a smoothed normal across a seam.
constexpr float kSameNormalCos = 0.99f;
// VolumeGroups::near_other: how near (fraction of the rest diagonal)
// another component's vertex makes a vertex near it.
constexpr float kVolumeNearReach = 0.02f;

// The paper's steps, named as in the kernels (kernels/tracking/):
// newtonStep, contactStop, marchToContact, tangentialRelaxation,
// skinnedRingOffset, smoothingStep, strainLimitStep. prev_gradients' w
// (ISK_GRADIENT_* of kernels/abi.h) says what the vertex's last projection step
// was.

// Eq. 4: one step of x towards the surface where the field's value gap
// (iso - f) closes, along the unit gradient, of sigma * gap / |gradient|
// clamped to +-max_step.
Eigen::Vector3f newtonStep(const Eigen::Vector3f& x,
                           const Eigen::Vector3f& unit, float value_gap,
                           float gradient_length, float sigma, float max_step) {
  const float length =
      std::clamp(sigma * value_gap / gradient_length, -max_step, max_step);
  return x + length * unit;
}

// Section 5, the contact stop: the gradient turned by more than the
// contact angle (cos_contact) since the vertex's last plain step.
bool contactStop(const Eigen::Vector3f& unit, const Eigen::Vector4f& prev,
                 float cos_contact) {
  return prev[3] == ISK_GRADIENT_STEP && unit.dot(prev.head<3>()) < cos_contact;
}

// The contact march's stop: the contact function's gradient (unit) turned
// back, by more than 90 degrees, since the vertex's last step towards the
// contact surface (frame: that step's c and unit normal). The march passed
// the point nearest to a contact surface it cannot reach (c has a minimum
// above 0 there); Newton steps about that minimum flip direction at every
// step and leave the vertex wherever the frame's last step does, so it
// stops there, at a contact.
bool contactMarchStop(const Eigen::Vector3f& unit, float prev_kind,
                      const Eigen::Vector4f& frame) {
  return prev_kind == ISK_GRADIENT_TO_CONTACT &&
         unit.dot(frame.tail<3>()) < 0.f;
}

// The contact by home field: a vertex that another part's field has
// entered (by `entered` over its rest margin, more than contact_entry) up
// to home_floor (h + entered >= its part's surface value less
// contact_home_slack) marches to the contact surface c = entered +
// contact_gap = 0 instead of its iso value, and stops there, or where its
// gradient turns back (contactMarchStop); unless its
// home field h is below home_minimum (its part's surface value less
// contact_home_reach): skinning carried it out of its own part, and it stops
// where it is, converged.
// kContactMarchNone: not held, the paper's
// march goes on; kContactMarchStepped: x stepped towards the contact surface;
// otherwise the state the vertex stops in.
constexpr int kContactMarchNone = -1;
constexpr int kContactMarchStepped = -2;
int marchToContact(Eigen::Vector3f* x, float* prev_kind, Eigen::Vector4f* frame,
                   float f, float iso, const HomeSamples& home, float entered,
                   float home_floor, float home_minimum,
                   const SurfaceTrackingOptions& options, float max_step,
                   float min_gradient) {
  bool marching_to_contact = *prev_kind == ISK_GRADIENT_TO_CONTACT;
  // Out of the other part's grip (left through the surface): back to the
  // paper's march.
  if (marching_to_contact && f < iso - options.tolerance) {
    marching_to_contact = false;
    *prev_kind = ISK_GRADIENT_UNSET;
  }
  if (!(home.home[0] > 0.f &&
        (marching_to_contact ||
         (f > iso + options.tolerance && entered > options.contact_entry &&
          home.home[0] + entered >= home_floor))))
    return kContactMarchNone;
  if (!marching_to_contact && !(home.home[0] >= home_minimum))
    return static_cast<int>(TrackState::kConverged);
  const float c = entered + options.contact_gap;
  if (marching_to_contact && c <= options.tolerance)
    return static_cast<int>(TrackState::kContact);
  const Eigen::Vector3f gc = (home.other - home.home).tail<3>();
  const float gc_len = gc.norm();
  if (!(gc_len > min_gradient)) return static_cast<int>(TrackState::kLost);
  if (contactMarchStop(gc / gc_len, *prev_kind, *frame))
    return static_cast<int>(TrackState::kContact);
  *prev_kind = ISK_GRADIENT_TO_CONTACT;
  // The relaxation's surface: the contact surface c = 0.
  *frame << c, gc.x() / gc_len, gc.y() / gc_len, gc.z() / gc_len;
  *x = newtonStep(*x, gc / gc_len, -c, gc_len, options.sigma, max_step);
  return kContactMarchStepped;
}

// Eq. 5, 6: x moved by mu times its ring's weighted centroid offset, within
// the tangent plane of the surface it marches to (frame: signed distance,
// unit normal); mu fades the move out one unit of distance away.
Eigen::Vector3f tangentialRelaxation(const Eigen::Vector3f& x,
                                     const Eigen::Vector3f& centroid,
                                     const Eigen::Vector4f& frame) {
  const Eigen::Vector3f unit = frame.tail<3>();
  const float t = std::abs(frame[0]) - 1.f;
  const float mu = std::max(0.f, 1.f - t * t * t * t);
  Eigen::Vector3f d = centroid - x;
  d -= d.dot(unit) * unit;
  return x + mu * d;
}

// Skinned-ring relaxation (surface_tracking.hpp): the skinned ring's offset
// from its vertex, offset = sum_j w_j s_j - s, within the plane normal to
// the skinned normal n (not unit); the whole offset where n vanishes.
Eigen::Vector3f skinnedRingOffset(const Eigen::Vector3f& offset,
                                  const Eigen::Vector3f& n) {
  const float length2 = n.squaredNorm();
  if (!(length2 > 0.f) || !std::isfinite(length2)) return offset;
  return offset - (offset.dot(n) / length2) * n;
}

// Eq. 7: one localized Laplacian step, the offset d to the near centroid
// weighted by beta (b, contacts) and the tangential part of it by gamma
// (c, creases).
Eigen::Vector3f smoothingStep(const Eigen::Vector3f& x,
                              const Eigen::Vector3f& d,
                              const Eigen::Vector3f& tangential, float b,
                              float c) {
  return x + b * d + (1.f - b) * c * tangential;
}

// The crease gate (surface_tracking.hpp): a crease vertex's source value of
// gamma, from its ring's vector area now and skinned (the sum over the
// closed ring of (x_j - x) x (x_j+1 - x)), the offset of its near centroid
// from it now and skinned (shift, skinned_shift), its near neighbours' mean
// rest length, and the largest stretch of a spoke beyond its skinned length
// in rest lengths. 1 where the ring has no area now (no plane to shift in)
// or the skinned ring none (no layout to compare with).
float creaseGate(const Eigen::Vector3f& area,
                 const Eigen::Vector3f& skinned_area,
                 const Eigen::Vector3f& shift,
                 const Eigen::Vector3f& skinned_shift, float mean_length,
                 float stretch) {
  const float length = area.norm();
  const float skinned_length2 = skinned_area.squaredNorm();
  if (!(length > 0.f) || !std::isfinite(length) || !(skinned_length2 > 0.f) ||
      !std::isfinite(skinned_length2) || !(mean_length > 0.f))
    return 1.f;
  const float ratio = area.dot(skinned_area) / skinned_length2;
  const float crushed =
      std::clamp((ISK_CREASE_AREA_NONE - ratio) /
                     (ISK_CREASE_AREA_NONE - ISK_CREASE_AREA_FULL),
                 0.f, 1.f);
  const Eigen::Vector3f unit = area / length;
  Eigen::Vector3f moved = shift - skinned_shift;
  moved -= moved.dot(unit) * unit;
  const float shifted =
      std::clamp((moved.norm() / mean_length - ISK_CREASE_SHIFT_NONE) /
                     (ISK_CREASE_SHIFT_FULL - ISK_CREASE_SHIFT_NONE),
                 0.f, 1.f);
  const float stretched =
      std::clamp((stretch - ISK_CREASE_STRETCH_NONE) /
                     (ISK_CREASE_STRETCH_FULL - ISK_CREASE_STRETCH_NONE),
                 0.f, 1.f);
  return std::max(std::max(crushed, shifted), stretched);
}

// Volume restoration (surface_tracking.hpp): how far vertex x moved inward
// from its skinned position s along the skinned normal (made unit), times
// (1 - gamma), for the vertices that converged to their iso value where
// beta = 0; 0 for the others (contacts, creases, still marching, lost,
// untracked).
float volumeRestoreWeight(TrackState state, float beta, float gamma,
                          const Eigen::Vector3f& x, const Eigen::Vector3f& s,
                          const Eigen::Vector3f& skinned_normal, float sign) {
  if (state != TrackState::kConverged || beta > 0.f) return 0.f;
  const float length = skinned_normal.norm();
  if (!(length > 0.f) || !std::isfinite(length)) return 0.f;
  const float inward = -sign * (x - s).dot(skinned_normal) / length;
  return inward > 0.f ? inward * (1.f - gamma) : 0.f;
}

// A group's fraction lambda: its missing volume over the weighted sum of
// its vertices' inward moves (sum w A), in [0, limit].
float volumeRestoreFraction(double missing, double weighted, float limit) {
  if (!(weighted > 0.0) || !(missing > 0.0)) return 0.f;
  return static_cast<float>(std::min(missing / weighted, double{limit}));
}

// The fraction after the step, where the group gained more volume than it
// missed (`gained`, measured after the step with `fraction`): the volume
// grows faster than linearly with the step on a small or sharply curved
// part, so the step is scaled by missing / gained (a secant step) and the
// part is not pushed past its rest volume. Unchanged elsewhere.
float volumeRestoreCorrection(double missing, double gained, float fraction) {
  if (!(fraction > 0.f) || !(missing > 0.0) || !(gained > missing))
    return fraction;
  return static_cast<float>(fraction * (missing / gained));
}

// A vertex's limit L: volume_restore, at most ISK_VOLUME_NEAR_LIMIT near
// another component of the mesh.
float volumeRestoreLimit(bool near_other, float volume_restore) {
  return near_other ? std::min(volume_restore, ISK_VOLUME_NEAR_LIMIT)
                    : volume_restore;
}

// How far a vertex of weight w moves for its group's fraction (capped at
// the vertex's limit) times `factor`: 1 for the step, then the secant's
// corrected / fraction - 1 for the step back, so that the step back scales
// every vertex's move alike, capped or not.
float volumeRestoreDistance(float fraction, float factor, float limit,
                            float weight) {
  return std::min(fraction, limit) * factor * weight;
}

// The secant step back's factor (see volumeRestoreDistance): the
// corrected fraction over the first less 1; where only the contact bulge
// stepped (fraction 0, bulge fraction above 0), missing / gained - 1 when
// the group gained more than it missed; 0 elsewhere.
float volumeRestoreBackFactor(float fraction, float corrected, float bulge,
                              double missing, double gained) {
  if (fraction > 0.f) return corrected / fraction - 1.f;
  if (!(bulge > 0.f) || !(missing > 0.0) || !(gained > missing)) return 0.f;
  return static_cast<float>(missing / gained) - 1.f;
}

// The step: `distance` out along the unit skinned normal (times its sign).
Eigen::Vector3f volumeRestoreStep(const Eigen::Vector3f& x,
                                  const Eigen::Vector3f& skinned_normal,
                                  float sign, float distance) {
  return x + (sign * distance) * skinned_normal.normalized();
}

// The contact bulge's band at v after one more ring: the largest of its
// own and each neighbour's less the edge's rest length over the reach.
// band(i), length(i): the ring's i-th neighbour's band and edge length.
template <typename Bands, typename Lengths>
float contactBandStep(float own, int count, Bands band, Lengths length,
                      float reach) {
  float b = own;
  for (int i = 0; i < count; ++i) b = std::max(b, band(i) - length(i) / reach);
  return b;
}

// A vertex's contact bulge weight u: its band times (1 - gamma) times the
// mean rest length of its ring edges, for a converged vertex away from
// contacts (beta = 0) and from other components; 0 for the others.
float contactBulgeWeight(TrackState state, float beta, float gamma,
                         bool near_other, float band, float mean_length) {
  if (state != TrackState::kConverged || beta > 0.f || near_other ||
      !(band > 0.f))
    return 0.f;
  return band * (1.f - gamma) * mean_length;
}

// The contact bulge's clearance at a band vertex: 1 where the composed
// field at its probe (out along its push) is below its iso value by
// ISK_BULGE_CLEARANCE_WIDTH or more, falling linearly to 0 where it reaches
// the iso value: another part's surface is within the probe's reach.
float contactBulgeClearance(float probe_value, float iso) {
  return std::clamp((iso - probe_value) / ISK_BULGE_CLEARANCE_WIDTH, 0.f, 1.f);
}

// What a group's inward moves cannot give back at volume_restore times
// their sum (sum w A): the volume left to the contact bulge, 0 where they
// can. A frame needs the bulge (its band, probe and weights) only where
// some group has some.
double contactBulgeMissing(double missing, double weighted,
                           float volume_restore) {
  return std::max(missing - double{volume_restore} * weighted, 0.0);
}

// A group's contact bulge fraction kappa: what the inward moves cannot give
// back at volume_restore times their sum, over the sum of the bulge
// weights (sum u A), in [0, limit].
float contactBulgeFraction(double missing, double weighted,
                           float volume_restore, double bulge_weighted,
                           float limit) {
  const double rest = contactBulgeMissing(missing, weighted, volume_restore);
  if (!(rest > 0.0) || !(bulge_weighted > 0.0)) return 0.f;
  return static_cast<float>(std::min(rest / bulge_weighted, double{limit}));
}

// The strain limit's Jacobi step for one vertex: its offset d from its
// skinned position moved, for each ring edge whose offsets differ by more
// than limit(i) * rest length, by half the excess towards the neighbour's
// offset, over the ring's size (not over the violated edges: the step stays
// continuous as an edge starts to violate). neighbour_offset(i),
// rest_length(i) and limit(i): the ring's i-th edge. *moved: whether an edge
// was violated.
template <typename Offsets, typename Lengths, typename Limits>
Eigen::Vector3f strainLimitStep(const Eigen::Vector3f& d, int count,
                                Offsets neighbour_offset, Lengths rest_length,
                                Limits limit, bool* moved) {
  Eigen::Vector3f correction = Eigen::Vector3f::Zero();
  *moved = false;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3f diff = d - neighbour_offset(i);
    const float length = std::sqrt(diff.dot(diff));
    const float excess = length - limit(i) * rest_length(i);
    if (excess > 0.f) {
      correction -= (0.5f * excess / length) * diff;
      *moved = true;
    }
  }
  if (!*moved) return d;
  return d + correction / static_cast<float>(count);
}

// The fold guard's test. A triangle's normal (corners p0, p1, p2,
// counter-clockwise; unnormalized), written out term by term as in the
// kernel.
Eigen::Vector3f triangleNormal(const Eigen::Vector3f& p0,
                               const Eigen::Vector3f& p1,
                               const Eigen::Vector3f& p2) {
  const Eigen::Vector3f a = p1 - p0, b = p2 - p0;
  return Eigen::Vector3f(a.y() * b.z() - a.z() * b.y(),
                         a.z() * b.x() - a.x() * b.z(),
                         a.x() * b.y() - a.y() * b.x());
}
float dot3(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return a.x() * b.x() + a.y() * b.y() + a.z() * b.z();
}
// x / ISK_FOLD_RAMP clamped to [0, 1].
float foldRamp(float x) {
  return std::min(std::max(x / ISK_FOLD_RAMP, 0.f), 1.f);
}

// The fold guard's frame of a triangle (corners q0, q1, q2 skinned, their
// skinned normals summed in `normal_sum`): its skinned unit normal, the unit
// normal sum, and the allowance, how far the skinned triangle does not
// oppose the sum (0 where skinning folded it itself, as in a deep bend's
// crease: not the tracking's to undo; 0 for a degenerate triangle).
FoldFrame foldFrame(const Eigen::Vector3f& q0, const Eigen::Vector3f& q1,
                    const Eigen::Vector3f& q2,
                    const Eigen::Vector3f& normal_sum) {
  FoldFrame out;
  const Eigen::Vector3f skinned = triangleNormal(q0, q1, q2);
  const float skinned_length = std::sqrt(dot3(skinned, skinned));
  const float sum_length = std::sqrt(dot3(normal_sum, normal_sum));
  if (!(skinned_length > 0.f && sum_length > 0.f)) return out;
  out.skinned = skinned / skinned_length;
  out.expected = normal_sum / sum_length;
  out.allowance = foldRamp(dot3(out.skinned, out.expected) + ISK_FOLD_RAMP);
  return out;
}
// A triangle's fold weight, in [0, 1]: how far its normal `now` opposes
// both its skinned unit normal and the unit sum of its corners' skinned
// normals (`frame`, from foldFrame), each cosine ramping over ISK_FOLD_RAMP
// so that rounding moves the weight by rounding, not from 0 to 1; times the
// frame's allowance. Both directions: a triangle at a hard edge, whose
// corners' normals are another face's, is not folded by a small offset.
float foldWeight(const Eigen::Vector3f& now, const FoldFrame& frame) {
  if (!(frame.allowance > 0.f)) return 0.f;
  const float length = std::sqrt(dot3(now, now));
  if (!(length > 0.f)) return 0.f;  // degenerate: no direction
  return foldRamp(-dot3(now, frame.expected) / length) *
         foldRamp(-dot3(now, frame.skinned) / length) * frame.allowance;
}

// The tilt guard's test: how far the triangle's normal `now` turned past
// `cosine` from both its skinned unit normal and the unit sum of its
// corners' skinned normals (each ramped as in foldWeight), times the frame's
// allowance.
float tiltWeight(const Eigen::Vector3f& now, const FoldFrame& frame,
                 float cosine) {
  if (!(frame.allowance > 0.f)) return 0.f;
  const float length = std::sqrt(dot3(now, now));
  if (!(length > 0.f)) return 0.f;
  return foldRamp(cosine - dot3(now, frame.expected) / length) *
         foldRamp(cosine - dot3(now, frame.skinned) / length) * frame.allowance;
}

}  // namespace

float tiltGuardCosine(const SurfaceTrackingOptions& options) {
  return std::cos(options.tilt_guard_degrees * static_cast<float>(M_PI) /
                  180.f);
}

bool restoresVolumeAgain(const SurfaceTrackingOptions& options) {
  return options.restore_again_steps > 0 && options.volume_restore > 0.f &&
         options.strain_limit_steps > 0;
}

float tiltGuardScale(const SurfaceTrackingOptions& options) {
  const float span = options.strain_limit - options.fold_strain_limit;
  if (!options.fold_guard || !(options.tilt_guard_degrees > 0.f) ||
      !(span > 0.f))
    return 0.f;
  return std::min(
      std::max((options.strain_limit - options.tilt_strain_limit) / span, 0.f),
      1.f);
}

Validation SurfaceTrackingOptions::validate() const {
  auto bad = [](const std::string& what) { return Validation::fail(what); };
  if (rounds < 0 || rounds > 1000)
    return bad("rounds " + std::to_string(rounds) + ": expected 0..1000");
  if (projection_steps < 1 || projection_steps > 100)
    return bad("projection_steps " + std::to_string(projection_steps) +
               ": expected 1..100");
  if (!(sigma > 0 && sigma <= 1))
    return bad("sigma " + std::to_string(sigma) + ": expected (0, 1]");
  if (!(contact_angle_degrees > 0 && contact_angle_degrees <= 180))
    return bad("contact_angle_degrees " +
               std::to_string(contact_angle_degrees) + ": expected (0, 180]");
  if (!(tolerance > 0 && tolerance < 1))
    return bad("tolerance " + std::to_string(tolerance) +
               ": expected field units in (0, 1)");
  if (!(max_step > 0 && max_step <= 1))
    return bad("max_step " + std::to_string(max_step) +
               ": expected a fraction of the diagonal in (0, 1]");
  if (!(contact_entry >= tolerance && contact_entry < 1))
    return bad("contact_entry " + std::to_string(contact_entry) +
               ": expected field units in [tolerance, 1)");
  if (!(contact_home_slack >= 0 && contact_home_slack <= 1))
    return bad("contact_home_slack " + std::to_string(contact_home_slack) +
               ": expected field units in [0, 1]");
  if (!(blend_contact_degrees >= 0 && blend_contact_degrees <= 180))
    return bad("blend_contact_degrees " +
               std::to_string(blend_contact_degrees) +
               ": expected degrees in [0, 180]");
  if (!(contact_home_reach >= 0 && contact_home_reach <= 1))
    return bad("contact_home_reach " + std::to_string(contact_home_reach) +
               ": expected field units in [0, 1]");
  if (!(rest_crease_degrees >= 0 && rest_crease_degrees <= 180))
    return bad("rest_crease_degrees " + std::to_string(rest_crease_degrees) +
               ": expected degrees in [0, 180]");
  if (!(volume_restore >= 0 && volume_restore <= 3))
    return bad("volume_restore " + std::to_string(volume_restore) +
               ": expected a fraction in [0, 3]");
  if (!(contact_bulge >= 0 && contact_bulge <= 10))
    return bad("contact_bulge " + std::to_string(contact_bulge) +
               ": expected mean edge lengths in [0, 10]");
  if (!(contact_bulge_radius > 0 && contact_bulge_radius <= 1))
    return bad("contact_bulge_radius " + std::to_string(contact_bulge_radius) +
               ": expected a fraction of the diagonal in (0, 1]");
  if (!(contact_bulge_clearance >= 0 && contact_bulge_clearance <= 10))
    return bad("contact_bulge_clearance " +
               std::to_string(contact_bulge_clearance) +
               ": expected largest pushes in [0, 10]");
  if (contact_bulge_steps < 0 || contact_bulge_steps > 1000)
    return bad("contact_bulge_steps " + std::to_string(contact_bulge_steps) +
               ": expected 0 to 1000");
  if (!(contact_gap >= 0 && contact_gap < 0.5f))
    return bad("contact_gap " + std::to_string(contact_gap) +
               ": expected field units in [0, 0.5)");
  if (!(min_gradient >= 0 && std::isfinite(min_gradient)))
    return bad("min_gradient " + std::to_string(min_gradient) +
               ": expected >= 0");
  if (beta_diffusion < 0 || beta_diffusion > 1000)
    return bad("beta_diffusion " + std::to_string(beta_diffusion) +
               ": expected 0..1000");
  if (!(smoothing_radius >= 0 && smoothing_radius <= 1))
    return bad("smoothing_radius " + std::to_string(smoothing_radius) +
               ": expected a fraction of the diagonal in [0, 1]");
  if (smoothing_steps < 0 || smoothing_steps > 1000)
    return bad("smoothing_steps " + std::to_string(smoothing_steps) +
               ": expected 0..1000");
  if (crease_diffusion < 0 || crease_diffusion > 1000)
    return bad("crease_diffusion " + std::to_string(crease_diffusion) +
               ": expected 0..1000");
  if (crease_steps < 0 || crease_steps > 1000)
    return bad("crease_steps " + std::to_string(crease_steps) +
               ": expected 0..1000");
  if (!(strain_limit >= 0 && strain_limit <= 100))
    return bad("strain_limit " + std::to_string(strain_limit) +
               ": expected a fraction of the rest length in [0, 100]");
  if (strain_limit_steps < 0 || strain_limit_steps > 1000)
    return bad("strain_limit_steps " + std::to_string(strain_limit_steps) +
               ": expected 0..1000");
  if (restore_again_steps < 0 || restore_again_steps > 1000)
    return bad("restore_again_steps " + std::to_string(restore_again_steps) +
               ": expected 0..1000");
  if (!(fold_strain_limit >= 0 && fold_strain_limit <= 100))
    return bad("fold_strain_limit " + std::to_string(fold_strain_limit) +
               ": expected a fraction of the rest length in [0, 100]");
  if (fold_rings < 0 || fold_rings > 16)
    return bad("fold_rings " + std::to_string(fold_rings) + ": expected 0..16");
  if (fold_check_steps < 1 || fold_check_steps > 1000)
    return bad("fold_check_steps " + std::to_string(fold_check_steps) +
               ": expected 1..1000");
  if (!(tilt_guard_degrees >= 0 && tilt_guard_degrees < 180))
    return bad("tilt_guard_degrees " + std::to_string(tilt_guard_degrees) +
               ": expected degrees in [0, 180) (0: off)");
  if (!(tilt_strain_limit >= 0 && tilt_strain_limit <= 100))
    return bad("tilt_strain_limit " + std::to_string(tilt_strain_limit) +
               ": expected a fraction of the rest length in [0, 100]");
  if (!(history_keep >= 0.f && history_keep <= 1.f))
    return bad("history_keep " + std::to_string(history_keep) +
               ": expected 0..1");
  const int cells = detail::tuningOf(*this).neighbourhood_cells;
  if (cells < 0 || cells > 16)
    return bad("neighbourhood_cells " + std::to_string(cells) +
               ": expected 0 (the device's choice) to 16");
  return Validation::ok();
}

const char* trackStateName(TrackState state) {
  switch (state) {
    case TrackState::kMarching:
      return "marching";
    case TrackState::kConverged:
      return "converged";
    case TrackState::kContact:
      return "contact";
    case TrackState::kLost:
      return "lost";
    case TrackState::kUntracked:
      return "untracked";
    case TrackState::kCrease:
      return "crease";
  }
  return "?";
}

int TrackingMesh::trackedCount() const {
  int count = 0;
  for (int v = 0; v < vertexCount(); ++v)
    if (iso_values[v] > 0 && rings.representative[v] == v) ++count;
  return count;
}

namespace {

// TrackingMesh::build's steps.

void checkIsoValues(const Mesh& mesh, const std::vector<float>& iso_values) {
  if (static_cast<int>(iso_values.size()) != mesh.vertexCount())
    throw Error(ErrorCode::kInvalidArgument,
                "surface tracking: " + std::to_string(iso_values.size()) +
                    " iso values for " + std::to_string(mesh.vertexCount()) +
                    " vertices");
  for (size_t v = 0; v < iso_values.size(); ++v)
    if (!(iso_values[v] >= 0 && iso_values[v] <= 1))
      throw Error(ErrorCode::kInvalidArgument,
                  "surface tracking: vertex " + std::to_string(v) + " (" +
                      mesh.describeVertex(static_cast<int>(v)) +
                      ") has iso value " + std::to_string(iso_values[v]) +
                      ", expected [0, 1]");
}

// Each ring entry's rest length |neighbour - vertex|.
std::vector<float> restRingLengths(const Mesh& mesh, const OneRings& rings) {
  std::vector<float> lengths(rings.neighbours.size());
  for (int v = 0; v < mesh.vertexCount(); ++v)
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
      lengths[i] =
          (mesh.positions.row(rings.neighbours[i]) - mesh.positions.row(v))
              .norm();
  return lengths;
}

// Normal adjacency over the welded mesh: a vertex gathers the triangles of
// every vertex of its group whose rest normal agrees with its own.
VertexTriangleAdjacency weldedNormalAdjacency(const Mesh& mesh,
                                              const OneRings& rings) {
  VertexTriangleAdjacency out;
  const int vertex_count = mesh.vertexCount();
  const VertexTriangleAdjacency plain =
      VertexTriangleAdjacency::build(mesh.triangles, vertex_count);
  std::vector<std::vector<int>> members(vertex_count);
  for (int v = 0; v < vertex_count; ++v)
    members[rings.representative[v]].push_back(v);
  out.offsets.assign(vertex_count + 1, 0);
  for (int v = 0; v < vertex_count; ++v) {
    out.offsets[v] = static_cast<uint32_t>(out.triangles.size());
    const Eigen::Vector3f n = mesh.normals.row(v).transpose();
    for (int u : members[rings.representative[v]]) {
      if (u != v && !(mesh.normals.row(u).dot(n) >= kSameNormalCos)) continue;
      out.triangles.insert(out.triangles.end(),
                           plain.triangles.begin() + plain.offsets[u],
                           plain.triangles.begin() + plain.offsets[u + 1]);
    }
  }
  out.offsets[vertex_count] = static_cast<uint32_t>(out.triangles.size());
  return out;
}

// The composition's blended pairs, for activePartners.
std::vector<TrackingMesh::PartnerPair> partnerPairs(
    const ImplicitFields& fields) {
  std::vector<TrackingMesh::PartnerPair> out;
  for (const int k : fields.composition.blended_pairs) {
    const FieldPair& pair = fields.composition.pairs.at(k);
    TrackingMesh::PartnerPair partner;
    partner.field_a = pair.field_a;
    partner.field_b = pair.field_b;
    partner.joint_a = fields.grids.grids.at(pair.field_a).joint;
    partner.joint_b = fields.grids.grids.at(pair.field_b).joint;
    partner.blend = pair.op == CompositionOperator::kBlend;
    out.push_back(partner);
  }
  return out;
}

// Each vertex's home field (its part's field, -1: none), rest margin (how
// far the other parts' fields exceed it at rest, where they already do) and
// its part's surface value.
void homeFieldsAndMargins(const Mesh& mesh, const ImplicitFields& fields,
                          TrackingMesh* out_mesh,
                          std::vector<int>* rest_other_field) {
  TrackingMesh& out = *out_mesh;
  const int vertex_count = mesh.vertexCount();
  const int field_count = out.field_count;
  out.home_field.assign(vertex_count, -1);
  out.home_margin.assign(vertex_count, 0.f);
  rest_other_field->assign(vertex_count, -1);
  const std::vector<int>& vertex_joint = fields.partition.vertex_joint;
  if (static_cast<int>(vertex_joint.size()) == vertex_count &&
      field_count > 0) {
    for (int v = 0; v < vertex_count; ++v) {
      const int joint = vertex_joint[v];
      if (joint >= 0 &&
          joint < static_cast<int>(fields.grids.field_of_joint.size()))
        out.home_field[v] = fields.grids.field_of_joint[joint];
    }
    int joint_count = 0;
    for (const FieldGrid& g : fields.grids.grids)
      joint_count = std::max(joint_count, g.joint + 1);
    const TransformList identity(joint_count, Eigen::Affine3f::Identity());
    const ComposedFieldSampler sampler(fields.grids, identity,
                                       &fields.composition);
    std::vector<Eigen::Vector4f> per_field(field_count);
    for (int v = 0; v < vertex_count; ++v) {
      if (out.home_field[v] < 0) continue;
      sampler.sample(mesh.positions.row(v).transpose(), per_field.data());
      const HomeSamples home = homeSamples(out, nullptr, v, per_field.data());
      out.home_margin[v] = std::max(0.f, home.other[0] - home.home[0]);
      // The rest crease's other part: the field homeSamples took.
      if (out.iso_values[v] > 0 &&
          home.other[0] >= out.iso_values[v] - TrackingMesh::kRestCreaseReach)
        for (int i = 0; i < field_count; ++i)
          if (i != out.home_field[v] && per_field[i][0] == home.other[0]) {
            (*rest_other_field)[v] = i;
            break;
          }
    }
  }
  // Each part's surface value: the median of its tracked vertices' iso
  // values (a poor fit puts the skin off the field's 0.5), its layers'
  // (clothes over it, bone_partition.hpp) left out.
  out.home_surface.assign(vertex_count, 0.f);
  std::vector<std::vector<float>> by_field(std::max(field_count, 0));
  const std::vector<uint8_t>& layer = fields.partition.vertex_layer;
  for (int v = 0; v < vertex_count; ++v)
    if (out.home_field[v] >= 0 && out.home_field[v] < field_count &&
        out.iso_values[v] > 0 &&
        !(static_cast<int>(layer.size()) == vertex_count && layer[v]))
      by_field[out.home_field[v]].push_back(out.iso_values[v]);
  std::vector<float> median(by_field.size(), 0.f);
  for (size_t i = 0; i < by_field.size(); ++i) {
    std::vector<float>& values = by_field[i];
    if (values.empty()) continue;
    const auto middle = values.begin() + values.size() / 2;
    std::nth_element(values.begin(), middle, values.end());
    median[i] = *middle;
  }
  for (int v = 0; v < vertex_count; ++v)
    if (out.home_field[v] >= 0 && out.home_field[v] < field_count)
      out.home_surface[v] = median[out.home_field[v]];
}

// TrackingMesh::rest_crease and rest_crease_pairs from each vertex's rest
// other field (homeFieldsAndMargins): kept where the composition does not
// pair the two fields and the vertex is in a volume group, away from other
// components (volume_groups must be built).
void restCreases(const ImplicitFields& fields,
                 const std::vector<int>& rest_other_field,
                 TrackingMesh* out_mesh) {
  TrackingMesh& out = *out_mesh;
  const int vertex_count = static_cast<int>(out.iso_values.size());
  out.rest_crease.assign(vertex_count, -1);
  out.rest_crease_pairs.clear();
  if (static_cast<int>(rest_other_field.size()) != vertex_count) return;
  const TrackingMesh::VolumeGroups& groups = out.volume_groups;
  std::map<std::pair<int, int>, int> pair_index;
  for (int v = 0; v < vertex_count; ++v) {
    const int h = out.home_field[v], o = rest_other_field[v];
    if (h < 0 || o < 0 ||
        static_cast<int>(groups.vertex_group.size()) != vertex_count ||
        groups.vertex_group[v] < 0 || groups.near_other[v])
      continue;
    bool paired = false;
    for (const FieldPair& pair : fields.composition.pairs)
      paired = paired || (pair.field_a == h && pair.field_b == o) ||
               (pair.field_a == o && pair.field_b == h);
    if (paired) continue;
    const auto [it, added] = pair_index.try_emplace(
        {h, o}, static_cast<int>(out.rest_crease_pairs.size()));
    if (added) {
      TrackingMesh::CreasePair crease;
      crease.home_field = h;
      crease.other_field = o;
      crease.home_joint = fields.grids.grids.at(h).joint;
      crease.other_joint = fields.grids.grids.at(o).joint;
      out.rest_crease_pairs.push_back(crease);
    }
    out.rest_crease[v] = it->second;
  }
}

// 21 bits spread to every third bit, for a Morton code.
uint64_t spreadBits(uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

// The tracked vertices by home field, then along a Morton curve of their
// rest positions: neighbouring work-items sample the same grids near the
// same nodes (cache reuse) and walk the same neighbourhood list.
std::vector<int> marchOrder(const Mesh& mesh, const TrackingMesh& out) {
  const int vertex_count = mesh.vertexCount();
  const Eigen::Vector3f lo = mesh.positions.colwise().minCoeff();
  const Eigen::Vector3f extent =
      (mesh.positions.colwise().maxCoeff().transpose() - lo)
          .cwiseMax(Eigen::Vector3f::Constant(1e-20f));
  std::vector<std::pair<uint64_t, int>> keyed;
  for (int v = 0; v < vertex_count; ++v) {
    if (!(out.iso_values[v] > 0) || out.rings.representative[v] != v) continue;
    const Eigen::Vector3f t =
        (mesh.positions.row(v).transpose() - lo).cwiseQuotient(extent);
    uint64_t code = 0;
    for (int a = 0; a < 3; ++a)
      code |= spreadBits(
                  static_cast<uint64_t>(std::clamp(t[a], 0.f, 1.f) * 1048575.f))
              << a;
    keyed.emplace_back(code, v);
  }
  std::stable_sort(
      keyed.begin(), keyed.end(), [&](const auto& a, const auto& b) {
        const int ha = out.home_field[a.second], hb = out.home_field[b.second];
        return ha != hb ? ha < hb : a.first < b.first;
      });
  std::vector<int> order;
  order.reserve(keyed.size());
  for (const auto& k : keyed) order.push_back(k.second);
  return order;
}

// Six times the volume of the tetrahedron (c0, a, b, c).
double tripleProduct(const Eigen::Vector3f& c0, const Eigen::Vector3f& a,
                     const Eigen::Vector3f& b, const Eigen::Vector3f& c) {
  const Eigen::Vector3d p = (a - c0).cast<double>(),
                        q = (b - c0).cast<double>(),
                        r = (c - c0).cast<double>();
  return p.dot(q.cross(r));
}

// TrackingMesh::VolumeGroups::near_other: per vertex, whether a
// representative of another connected component (`root` of the welded
// union-find, with at least one triangle) lies within kVolumeNearReach of
// the rest diagonal. Cells of that size, each vertex testing its 27.
template <typename Root>
std::vector<uint8_t> nearOtherComponent(const Mesh& mesh,
                                        const std::vector<int>& rep, Root root,
                                        const std::vector<int>& triangles) {
  const int n = mesh.vertexCount();
  std::vector<uint8_t> near(n, 0);
  Eigen::AlignedBox3f box;
  for (int v = 0; v < n; ++v) box.extend(mesh.positions.row(v).transpose());
  const float reach = kVolumeNearReach * box.diagonal().norm();
  if (!(reach > 0.f)) return near;
  auto cell = [&](int v) -> Eigen::Vector3i {
    return ((mesh.positions.row(v).transpose() - box.min()) / reach)
        .array()
        .floor()
        .cast<int>();
  };
  std::map<std::array<int, 3>, std::vector<int>> cells;
  for (int v = 0; v < n; ++v)
    if (rep[v] == v && triangles[root(v)] > 0) {
      const Eigen::Vector3i c = cell(v);
      cells[{c.x(), c.y(), c.z()}].push_back(v);
    }
  for (auto& [key, members] : cells)
    for (const int v : members) {
      const int own = root(v);
      const Eigen::Vector3f x = mesh.positions.row(v).transpose();
      for (int d = 0; d < 27 && !near[v]; ++d) {
        const auto other = cells.find(
            {key[0] + d % 3 - 1, key[1] + d / 3 % 3 - 1, key[2] + d / 9 - 1});
        if (other == cells.end()) continue;
        for (const int u : other->second)
          if (root(u) != own &&
              (mesh.positions.row(u).transpose() - x).norm() <= reach) {
            near[v] = 1;
            break;
          }
      }
    }
  for (int v = 0; v < n; ++v) near[v] = near[rep[v]];
  return near;
}

// The volume restoration's groups (TrackingMesh::VolumeGroups): the welded
// mesh's connected components with at most 1% of their vertices on a border
// and a rest volume above 1e-6 of their size cubed.
TrackingMesh::VolumeGroups volumeGroups(const Mesh& mesh, const OneRings& rings,
                                        const BonePartition& partition) {
  const int n = mesh.vertexCount();
  const std::vector<int>& rep = rings.representative;
  std::vector<int> parent(n);
  for (int v = 0; v < n; ++v) parent[v] = v;
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::vector<std::array<int, 3>> welded;
  std::vector<int> source;  // the mesh triangle of each welded one
  const SurfaceOrientation orientation = SurfaceOrientation::of(mesh);
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    std::array<int, 3> c = {rep[mesh.triangles(t, 0)],
                            rep[mesh.triangles(t, 1)],
                            rep[mesh.triangles(t, 2)]};
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;  // degenerate
    if (orientation.triangle_sign[t] < 0) std::swap(c[1], c[2]);
    for (int k = 1; k < 3; ++k) {
      const int a = find(c[0]), b = find(c[k]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
    welded.push_back(c);
  }
  std::vector<int> vertices(n, 0), border(n, 0), triangles(n, 0);
  std::vector<Eigen::AlignedBox3f> boxes(n);
  for (int v = 0; v < n; ++v) {
    if (rep[v] != v) continue;
    const int root = find(v);
    ++vertices[root];
    border[root] += rings.kinds[v] == RingKind::kBoundary;
    boxes[root].extend(mesh.positions.row(v).transpose());
  }
  for (const auto& c : welded) ++triangles[find(c[0])];
  // Groups in order of their smallest vertex; rest volumes about each
  // group's first corner.
  std::vector<int> group_of_root(n, -1);
  std::vector<std::vector<std::array<int, 3>>> by_group;
  TrackingMesh::VolumeGroups out;
  for (const auto& c : welded) {
    const int root = find(c[0]);
    if (triangles[root] < 4 || 100 * border[root] > vertices[root]) continue;
    if (group_of_root[root] < 0) {
      group_of_root[root] = static_cast<int>(by_group.size());
      by_group.emplace_back();
    }
    by_group[group_of_root[root]].push_back(c);
  }
  auto at = [&](int v) -> Eigen::Vector3f {
    return mesh.positions.row(v).transpose();
  };
  out.triangle_offsets.push_back(0);
  for (size_t g = 0; g < by_group.size(); ++g) {
    const auto& list = by_group[g];
    const Eigen::Vector3f c0 = at(list[0][0]);
    double volume = 0;
    for (const auto& c : list)
      volume += tripleProduct(c0, at(c[0]), at(c[1]), at(c[2]));
    volume /= 6;
    const double size = boxes[find(list[0][0])].diagonal().norm();
    if (!(volume > 1e-6 * size * size * size)) continue;
    out.rest_volume.push_back(volume);
    for (const auto& c : list)
      out.corners.insert(out.corners.end(), c.begin(), c.end());
    out.triangle_offsets.push_back(static_cast<int>(out.corners.size() / 3));
  }
  out.vertex_group.assign(n, -1);
  out.vertex_area.assign(n, 0.f);
  out.normal_sign.assign(n, 1.f);
  std::vector<Eigen::Vector3f> outward(n, Eigen::Vector3f::Zero());
  for (int g = 0; g < out.groupCount(); ++g)
    for (int t = out.triangle_offsets[g]; t < out.triangle_offsets[g + 1];
         ++t) {
      const int* c = &out.corners[3 * static_cast<size_t>(t)];
      const Eigen::Vector3f face =
          (at(c[1]) - at(c[0])).cross(at(c[2]) - at(c[0]));
      for (int k = 0; k < 3; ++k) {
        out.vertex_area[c[k]] += face.norm() / 6.f;
        out.vertex_group[c[k]] = g;
        outward[c[k]] += face;
      }
    }
  for (int v = 0; v < n; ++v)
    if (out.vertex_group[v] >= 0 &&
        outward[v].dot(mesh.normals.row(v).transpose()) < 0.f)
      out.normal_sign[v] = -1.f;
  out.near_other = nearOtherComponent(mesh, rep, find, triangles);
  // Parts dressed in layers of clothes are left alone: the layers follow
  // the field, and moving the skin out alone would push it through them.
  const std::vector<uint8_t>& layers = partition.vertex_layer;
  const std::vector<int>& joint = partition.vertex_joint;
  if (static_cast<int>(layers.size()) == n &&
      static_cast<int>(joint.size()) == n) {
    for (int v = 0; v < n; ++v) {
      const int j = joint[v];
      const bool dressed =
          j >= 0 && j < static_cast<int>(partition.layer_triangles.size()) &&
          !partition.layer_triangles[j].empty();
      if (dressed || layers[v]) out.vertex_group[v] = -1;
    }
  }
  return out;
}

}  // namespace

TrackingMesh TrackingMesh::build(const Mesh& mesh,
                                 const ImplicitFields& fields) {
  mesh.validate().throwIfFailed("surface tracking");
  checkIsoValues(mesh, fields.iso_values);
  TrackingMesh out;
  out.rings = OneRings::build(mesh.positions, mesh.triangles);
  out.relaxation = RelaxationWeights::build(out.rings, mesh.positions);
  // The untracked joints' parts stay where skinning puts them: not smoothed
  // either, even beside a contact.
  for (const int v : fields.untracked_vertices)
    if (v >= 0 && v < mesh.vertexCount())
      out.relaxation.rules[v] = RelaxationRule::kFixed;
  out.iso_values = fields.iso_values;
  out.triangles = mesh.triangles;
  out.diagonal = boundingBoxDiagonal(mesh.positions);
  out.ring_lengths = restRingLengths(mesh, out.rings);
  out.normal_adjacency = weldedNormalAdjacency(mesh, out.rings);
  out.field_count = fields.grids.fieldCount();
  out.partner_pairs = partnerPairs(fields);
  std::vector<int> rest_other_field;
  homeFieldsAndMargins(mesh, fields, &out, &rest_other_field);
  out.march_order = marchOrder(mesh, out);
  out.volume_groups = volumeGroups(mesh, out.rings, fields.partition);
  restCreases(fields, rest_other_field, &out);
  return out;
}

TrackingLengths trackingLengths(const TrackingMesh& mesh,
                                const SurfaceTrackingOptions& options) {
  const int n = mesh.vertexCount();
  if (!mesh.vertex_diagonals.empty() &&
      static_cast<int>(mesh.vertex_diagonals.size()) != n)
    throw Error(
        ErrorCode::kInvalidArgument,
        "surface tracking: " + std::to_string(mesh.vertex_diagonals.size()) +
            " vertex diagonals for " + std::to_string(n) + " vertices");
  TrackingLengths out;
  out.max_step.resize(n);
  out.min_gradient.resize(n);
  out.smoothing_radius.resize(n);
  out.bulge_reach.resize(n);
  for (int v = 0; v < n; ++v) {
    const float diagonal = mesh.diagonalOf(v);
    out.bulge_reach[v] = options.contact_bulge_radius * diagonal;
    out.max_step[v] = options.max_step * diagonal;
    out.min_gradient[v] =
        diagonal > 0 ? options.min_gradient / diagonal : options.min_gradient;
    out.smoothing_radius[v] = options.smoothing_radius * diagonal;
  }
  return out;
}

namespace {

// The angle (radians) of the rotation between joints a's and b's skinning
// transforms: how far they turned relative to each other from the bind
// pose (pairJointAngles' measure).
float relativeTurn(const TransformList& skinning, int a, int b) {
  const Eigen::Quaternionf qa(skinning.at(a).rotation());
  const Eigen::Quaternionf qb(skinning.at(b).rotation());
  const Eigen::Quaternionf relative = qa.conjugate() * qb;
  return 2.f * std::atan2(relative.vec().norm(), std::abs(relative.w()));
}

}  // namespace

void dropBlendedRestCreases(TrackingMesh* mesh) {
  const size_t pairs = mesh->rest_crease_pairs.size();
  std::vector<int> total(pairs, 0), blended(pairs, 0);
  for (const int crease : mesh->rest_crease)
    if (crease >= 0) ++total[crease];
  for (const DislocationCandidate& c : mesh->dislocation_candidates) {
    if (c.vertex < 0 || c.vertex >= static_cast<int>(mesh->rest_crease.size()))
      continue;
    const int crease = mesh->rest_crease[c.vertex];
    if (crease >= 0 &&
        mesh->rest_crease_pairs[crease].other_joint == c.other_joint)
      ++blended[crease];
  }
  for (int& crease : mesh->rest_crease)
    if (crease >= 0 && blended[crease] > kBlendedRestCrease * total[crease])
      crease = -1;
}

std::vector<int> restCreaseShifts(const TrackingMesh& mesh,
                                  const TransformList& skinning,
                                  const SurfaceTrackingOptions& options) {
  const float limit =
      options.rest_crease_degrees * static_cast<float>(M_PI) / 180.f;
  std::vector<int> shifts(mesh.rest_crease_pairs.size(), 0);
  for (size_t k = 0; k < shifts.size(); ++k) {
    const TrackingMesh::CreasePair& pair = mesh.rest_crease_pairs[k];
    shifts[k] =
        relativeTurn(skinning, pair.home_joint, pair.other_joint) < limit;
  }
  return shifts;
}

std::vector<int> activePartners(const TrackingMesh& mesh,
                                const TransformList& skinning,
                                const SurfaceTrackingOptions& options) {
  const float limit =
      options.blend_contact_degrees * static_cast<float>(M_PI) / 180.f;
  constexpr int kMax = TrackingMesh::kMaxPartners;
  std::vector<int> partners(static_cast<size_t>(mesh.field_count) * kMax, -1);
  auto add = [&](int field, int partner) {
    int* row = &partners[static_cast<size_t>(field) * kMax];
    for (int k = 0; k < kMax; ++k) {
      if (row[k] < 0 || row[k] == partner) {
        row[k] = partner;
        return;
      }
    }
  };
  for (const TrackingMesh::PartnerPair& pair : mesh.partner_pairs) {
    if (!pair.blend) continue;
    // The joint's rotation from its bind pose, as pairJointAngles has it.
    if (!(relativeTurn(skinning, pair.joint_a, pair.joint_b) < limit)) continue;
    add(pair.field_a, pair.field_b);
    add(pair.field_b, pair.field_a);
  }
  return partners;
}

namespace {

// The 8 corners and 3 edge directions of grid's support box (grown by
// margin of its size per side) in model space.
struct PosedBox {
  Eigen::Vector3f corners[8];
  Eigen::Vector3f edges[3];
  Eigen::Vector3f lo, hi;  // the corners' axis-aligned bounds
};

PosedBox posedBox(const FieldGrid& grid, const Eigen::Affine3f& to_bone,
                  float margin) {
  const Eigen::Affine3f to_model = to_bone.inverse(Eigen::Affine);
  const Eigen::Vector3f grow = margin * (grid.box_max - grid.box_min);
  const Eigen::Vector3f lo = grid.box_min - grow;
  const Eigen::Vector3f hi = grid.box_max + grow;
  PosedBox out;
  for (int c = 0; c < 8; ++c)
    out.corners[c] = to_model * Eigen::Vector3f(c & 1 ? hi.x() : lo.x(),
                                                c & 2 ? hi.y() : lo.y(),
                                                c & 4 ? hi.z() : lo.z());
  for (int e = 0; e < 3; ++e) out.edges[e] = to_model.linear().col(e);
  out.lo = out.hi = out.corners[0];
  for (int c = 1; c < 8; ++c) {
    out.lo = out.lo.cwiseMin(out.corners[c]);
    out.hi = out.hi.cwiseMax(out.corners[c]);
  }
  return out;
}

bool separatedAlong(const PosedBox& a, const PosedBox& b,
                    const Eigen::Vector3f& axis) {
  if (!(axis.squaredNorm() > 1e-20f)) return false;  // degenerate axis
  float a_lo = a.corners[0].dot(axis), a_hi = a_lo;
  float b_lo = b.corners[0].dot(axis), b_hi = b_lo;
  for (int c = 1; c < 8; ++c) {
    const float pa = a.corners[c].dot(axis);
    const float pb = b.corners[c].dot(axis);
    a_lo = std::min(a_lo, pa);
    a_hi = std::max(a_hi, pa);
    b_lo = std::min(b_lo, pb);
    b_hi = std::max(b_hi, pb);
  }
  return a_hi < b_lo || b_hi < a_lo;
}

bool boxesMeet(const PosedBox& a, const PosedBox& b) {
  // Boxes whose bounds are apart do not meet: most pairs of a crowd's
  // fields (isk/implicit_crowd.hpp) are settled here, before the 15 axes.
  if ((a.hi.array() < b.lo.array()).any() ||
      (b.hi.array() < a.lo.array()).any())
    return false;
  // Separating axes of two parallelepipeds: the face normals of each and
  // the cross products of their edges.
  for (const PosedBox* box : {&a, &b})
    for (int e = 0; e < 3; ++e)
      if (separatedAlong(
              a, b, box->edges[(e + 1) % 3].cross(box->edges[(e + 2) % 3])))
        return false;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (separatedAlong(a, b, a.edges[i].cross(b.edges[j]))) return false;
  return true;
}

}  // namespace

bool posedBoxesMeet(const FieldGrid& a, const Eigen::Affine3f& a_to_bone,
                    const FieldGrid& b, const Eigen::Affine3f& b_to_bone,
                    float margin) {
  return boxesMeet(posedBox(a, a_to_bone, margin),
                   posedBox(b, b_to_bone, margin));
}

double FieldNeighbourhoods::meanListed() const {
  if (offsets.size() < 2) return 0;
  return static_cast<double>(entries.size()) / (offsets.size() - 1);
}

FieldNeighbourhoods fieldNeighbourhoods(
    const TrackingMesh& mesh, const FieldGridSet& grids,
    const std::vector<Eigen::Affine3f>& to_bone,
    const std::vector<int>& partners) {
  const int field_count = grids.fieldCount();
  if (static_cast<int>(to_bone.size()) != field_count)
    throw Error(ErrorCode::kInvalidArgument,
                "fieldNeighbourhoods: " + std::to_string(to_bone.size()) +
                    " transforms for " + std::to_string(field_count) +
                    " fields");
  if (field_count > FieldNeighbourhoods::kFieldMask)
    throw Error(ErrorCode::kInvalidArgument,
                "fieldNeighbourhoods: " + std::to_string(field_count) +
                    " fields, at most " +
                    std::to_string(FieldNeighbourhoods::kFieldMask));
  constexpr int kMax = TrackingMesh::kMaxPartners;
  const bool with_partners =
      partners.size() == static_cast<size_t>(field_count) * kMax;
  std::vector<PosedBox> boxes;
  boxes.reserve(field_count);
  for (int i = 0; i < field_count; ++i)
    boxes.push_back(posedBox(grids.grids[i], to_bone[i], 1e-3f));
  // Sweep and prune along x: boxes sorted by their lowest x, each tested
  // only against those that start before it ends (a box starting later is
  // apart from it along x, which boxesMeet would find first). A bound that
  // is not a number (a pose past float range) prunes nothing.
  auto low_x = [&](int i) {
    const float x = boxes[i].lo.x();
    return std::isnan(x) ? -std::numeric_limits<float>::infinity() : x;
  };
  auto high_x = [&](int i) {
    const float x = boxes[i].hi.x();
    return std::isnan(x) ? std::numeric_limits<float>::infinity() : x;
  };
  std::vector<int> by_low_x(field_count);
  for (int i = 0; i < field_count; ++i) by_low_x[i] = i;
  std::sort(by_low_x.begin(), by_low_x.end(), [&](int a, int b) {
    return low_x(a) < low_x(b) || (low_x(a) == low_x(b) && a < b);
  });
  std::vector<std::vector<int>> listed(field_count);
  for (int a = 0; a < field_count; ++a) {
    const int h = by_low_x[a];
    listed[h].push_back(h);
    const float end = high_x(h);
    for (int b = a + 1; b < field_count && !(low_x(by_low_x[b]) > end); ++b) {
      const int i = by_low_x[b];
      if (boxesMeet(boxes[std::min(h, i)], boxes[std::max(h, i)])) {
        listed[h].push_back(i);
        listed[i].push_back(h);
      }
    }
  }
  // The blended pairs by their first field.
  std::vector<std::vector<int>> pairs_of(field_count);
  for (size_t k = 0; k < mesh.partner_pairs.size(); ++k) {
    const TrackingMesh::PartnerPair& pair = mesh.partner_pairs[k];
    if (pair.field_a >= 0 && pair.field_a < field_count && pair.field_b >= 0 &&
        pair.field_b < field_count)
      pairs_of[pair.field_a].push_back(static_cast<int>(k));
  }
  std::vector<int> listed_in(field_count, -1);  // h whose list holds it
  FieldNeighbourhoods out;
  out.offsets.assign(1, 0);
  out.pair_offsets.assign(1, 0);
  for (int h = 0; h < field_count; ++h) {
    std::vector<int>& fields = listed[h];
    std::sort(fields.begin(), fields.end());
    for (const int i : fields) {
      listed_in[i] = h;
      bool partner = i == h;
      for (int k = 0; with_partners && k < kMax; ++k)
        partner = partner || partners[static_cast<size_t>(h) * kMax + k] == i;
      out.entries.push_back(partner ? i | FieldNeighbourhoods::kPartner : i);
    }
    out.offsets.push_back(static_cast<int>(out.entries.size()));
    const size_t first_pair = out.pairs.size();
    for (const int a : fields)
      for (const int k : pairs_of[a])
        if (listed_in[mesh.partner_pairs[k].field_b] == h)
          out.pairs.push_back(k);
    std::sort(out.pairs.begin() + first_pair, out.pairs.end());
    out.pair_offsets.push_back(static_cast<int>(out.pairs.size()));
  }
  return out;
}

void splitNeighbourhoodsIntoCells(
    FieldNeighbourhoods& neighbourhoods, const FieldGridSet& grids,
    const std::vector<Eigen::Affine3f>& to_bone,
    const std::vector<Eigen::AlignedBox3f>& occupied_boxes,
    int cells_per_axis) {
  if (cells_per_axis < 1 || cells_per_axis > 16)
    throw Error(
        ErrorCode::kInvalidArgument,
        "splitNeighbourhoodsIntoCells: " + std::to_string(cells_per_axis) +
            " cells per axis, expected 1 to 16");
  const int per_axis = cells_per_axis;
  const int cell_count = per_axis * per_axis * per_axis;
  const int field_count =
      static_cast<int>(std::max<size_t>(neighbourhoods.offsets.size(), 1)) - 1;
  if (grids.fieldCount() != field_count ||
      static_cast<int>(to_bone.size()) != field_count ||
      static_cast<int>(occupied_boxes.size()) != field_count)
    throw Error(ErrorCode::kInvalidArgument,
                "splitNeighbourhoodsIntoCells: neighbourhoods of " +
                    std::to_string(field_count) + " fields, " +
                    std::to_string(grids.fieldCount()) + " grids, " +
                    std::to_string(to_bone.size()) + " transforms, " +
                    std::to_string(occupied_boxes.size()) + " occupied boxes");
  // Each occupied box's corners in model space, grown by 1e-3 of its grid's
  // support box per side.
  std::vector<std::array<Eigen::Vector3f, 8>> corners(field_count);
  for (int i = 0; i < field_count; ++i) {
    const Eigen::AlignedBox3f& box = occupied_boxes[i];
    if (box.isEmpty()) continue;
    const FieldGrid& g = grids.grids[i];
    const Eigen::Vector3f grow = 1e-3f * (g.box_max - g.box_min).cwiseAbs();
    const Eigen::Vector3f lo = box.min() - grow, hi = box.max() + grow;
    const Eigen::Affine3f to_model = to_bone[i].inverse();
    for (int c = 0; c < 8; ++c)
      corners[i][c] = to_model * Eigen::Vector3f(c & 1 ? hi.x() : lo.x(),
                                                 c & 2 ? hi.y() : lo.y(),
                                                 c & 4 ? hi.z() : lo.z());
  }
  neighbourhoods.cells_per_axis = cells_per_axis;
  std::vector<int>& offsets = neighbourhoods.cell_offsets;
  std::vector<int>& entries = neighbourhoods.cell_entries;
  offsets.assign(1, 0);
  entries.clear();
  std::vector<std::vector<int>> cells(cell_count);
  for (int h = 0; h < field_count; ++h) {
    for (auto& cell : cells) cell.clear();
    const FieldGrid& g = grids.grids[h];
    const Eigen::Vector3f extent = g.box_max - g.box_min;
    for (int n = neighbourhoods.offsets[h]; n < neighbourhoods.offsets[h + 1];
         ++n) {
      const int entry = neighbourhoods.entries[n];
      const int i = entry & FieldNeighbourhoods::kFieldMask;
      if (i >= field_count || occupied_boxes[i].isEmpty()) continue;  // 0
      // The box in h's cell units (per_axis cells along each axis of h's box).
      Eigen::Vector3f lo = Eigen::Vector3f::Constant(
                          std::numeric_limits<float>::infinity()),
                      hi = -lo;
      for (const Eigen::Vector3f& corner : corners[i]) {
        const Eigen::Vector3f q =
            (to_bone[h] * corner - g.box_min).cwiseQuotient(extent) *
            static_cast<float>(per_axis);
        lo = lo.cwiseMin(q);
        hi = hi.cwiseMax(q);
      }
      int first[3], last[3];
      bool meets = true;
      for (int a = 0; a < 3; ++a) {
        if (!(std::isfinite(lo[a]) && std::isfinite(hi[a]))) {
          first[a] = 0;  // no bound: every cell
          last[a] = per_axis - 1;
          continue;
        }
        // 1e-3 of h's box (per_axis cells) on either side.
        const float margin = 1e-3f * static_cast<float>(per_axis);
        const float from = std::floor(lo[a] - margin);
        const float to = std::floor(hi[a] + margin);
        if (to < 0.f || from > static_cast<float>(per_axis - 1)) meets = false;
        first[a] = static_cast<int>(std::max(from, 0.f));
        last[a] =
            static_cast<int>(std::min(to, static_cast<float>(per_axis - 1)));
      }
      if (!meets) continue;
      for (int z = first[2]; z <= last[2]; ++z)
        for (int y = first[1]; y <= last[1]; ++y)
          for (int x = first[0]; x <= last[0]; ++x)
            cells[x + per_axis * (y + per_axis * z)].push_back(entry);
    }
    for (const auto& cell : cells) {
      entries.insert(entries.end(), cell.begin(), cell.end());
      offsets.push_back(static_cast<int>(entries.size()));
    }
  }
}

float homeFloor(const TrackingMesh& mesh, int vertex,
                const SurfaceTrackingOptions& options) {
  return mesh.home_surface[vertex] - options.contact_home_slack;
}

float homeMinimum(const TrackingMesh& mesh, int vertex,
                  const SurfaceTrackingOptions& options) {
  return mesh.home_surface[vertex] - options.contact_home_reach;
}

HomeSamples homeSamples(const TrackingMesh& mesh, const int* partners,
                        int vertex, const Eigen::Vector4f* per_field) {
  HomeSamples out;
  const int home = mesh.home_field[vertex];
  if (home < 0) return out;
  out.home = per_field[home];
  const int* row = partners ? partners + static_cast<size_t>(home) *
                                             TrackingMesh::kMaxPartners
                            : nullptr;
  for (int i = 0; i < mesh.field_count; ++i) {
    if (i == home) continue;
    bool partner = false;
    for (int k = 0; row && k < TrackingMesh::kMaxPartners; ++k)
      partner = partner || row[k] == i;
    if (partner) continue;
    if (per_field[i][0] > out.other[0]) out.other = per_field[i];
  }
  return out;
}

TrackingCounts countStates(const std::vector<TrackState>& states) {
  TrackingCounts c;
  for (TrackState s : states) {
    switch (s) {
      case TrackState::kMarching:
        ++c.marching;
        break;
      case TrackState::kConverged:
        ++c.converged;
        break;
      case TrackState::kContact:
        ++c.contact;
        break;
      case TrackState::kLost:
        ++c.lost;
        break;
      case TrackState::kUntracked:
        ++c.untracked;
        break;
      case TrackState::kCrease:
        ++c.crease;
        break;
    }
  }
  return c;
}

CpuSurfaceTracking::CpuSurfaceTracking(const FieldGridSet& fields,
                                       const Composition* composition,
                                       const TrackingMesh& mesh,
                                       const SurfaceTrackingOptions& options)
    : fields_(&fields),
      composition_(composition),
      mesh_(&mesh),
      options_(options) {
  options.validate().throwIfFailed("SurfaceTrackingOptions");
  if (mesh.rings.vertexCount() != mesh.vertexCount() ||
      mesh.relaxation.rules.size() != mesh.iso_values.size() ||
      mesh.rest_crease.size() != mesh.iso_values.size())
    throw Error(ErrorCode::kInvalidArgument,
                "CpuSurfaceTracking: the tracking mesh is inconsistent (built "
                "by TrackingMesh::build?)");
  lengths_ = trackingLengths(mesh, options);
}

void CpuSurfaceTracking::checkBegun(const char* stage) const {
  detail::checkBegun("CpuSurfaceTracking", stage, begun_);
}

void CpuSurfaceTracking::begin(const TransformList& skinning,
                               const Matrix3Xf& skinned_positions,
                               const Matrix3Xf& skinned_normals,
                               const Matrix3Xf* start) {
  const int n = mesh_->vertexCount();
  if (skinned_positions.rows() != n || skinned_normals.rows() != n ||
      (start && start->rows() != n))
    throw Error(
        ErrorCode::kInvalidArgument,
        "CpuSurfaceTracking::begin: " +
            std::to_string(skinned_positions.rows()) + " positions and " +
            std::to_string(skinned_normals.rows()) + " normals" +
            (start
                 ? " and " + std::to_string(start->rows()) + " start positions"
                 : std::string()) +
            " for a mesh of " + std::to_string(n) + " vertices");
  for (const FieldGrid& g : fields_->grids)
    if (g.joint < 0 || g.joint >= static_cast<int>(skinning.size()))
      throw Error(ErrorCode::kInvalidArgument,
                  "CpuSurfaceTracking::begin: a field belongs to joint " +
                      std::to_string(g.joint) + " but " +
                      std::to_string(skinning.size()) +
                      " transforms were given");
  // The last frame's states, for a history start (below).
  std::vector<TrackState> last_states;
  if (start) last_states = states_;
  skinning_ = skinning;
  partners_ = activePartners(*mesh_, skinning, options_);
  crease_shifts_ = restCreaseShifts(*mesh_, skinning, options_);
  neighbourhoods_ = fieldNeighbourhoods(
      *mesh_, *fields_, fieldTransforms(*fields_, skinning), partners_);
  positions_ = skinned_positions;
  skinned_ = skinned_positions;
  fallback_normals_ = skinned_normals;
  states_.resize(n);
  prev_.setZero(n, 4);
  relax_frames_.setZero(n, 4);
  for (int v = 0; v < n; ++v)
    states_[v] = mesh_->iso_values[v] > 0 && mesh_->rings.representative[v] == v
                     ? TrackState::kMarching
                     : TrackState::kUntracked;
  if (options_.dislocation_guard)
    for (const int v :
         dislocatedVertices(mesh_->dislocation_candidates, skinning))
      states_[v] = TrackState::kUntracked;
  if (start && static_cast<int>(last_states.size()) == n)
    for (int v = 0; v < n; ++v)
      if (states_[v] == TrackState::kMarching &&
          (last_states[v] == TrackState::kContact ||
           last_states[v] == TrackState::kCrease))
        positions_.row(v) =
            skinned_.row(v) +
            options_.history_keep * (start->row(v) - skinned_.row(v));
  beta_.assign(2 * static_cast<size_t>(n), 0.f);
  crease_sources_.assign(n, 0.f);
  times_ = {};
  begun_ = true;
}

void CpuSurfaceTracking::setState(const Matrix3Xf& positions,
                                  const std::vector<TrackState>& states,
                                  const Matrix4Xf& prev_gradients,
                                  const Matrix4Xf* relax_frames) {
  checkBegun("setState");
  const int n = mesh_->vertexCount();
  if (positions.rows() != n || static_cast<int>(states.size()) != n ||
      prev_gradients.rows() != n || (relax_frames && relax_frames->rows() != n))
    throw Error(ErrorCode::kInvalidArgument,
                "CpuSurfaceTracking::setState: expected " + std::to_string(n) +
                    " rows");
  positions_ = positions;
  states_ = states;
  prev_ = prev_gradients;
  if (relax_frames) relax_frames_ = *relax_frames;
}

Eigen::Vector4f CpuSurfaceTracking::sampleAt(
    const ComposedFieldSampler& sampler, int v, const Eigen::Vector3f& x,
    Eigen::Vector4f* per_field, HomeSamples* home) const {
  const int h = mesh_->home_field[v];
  if (detail::tuningOf(options_).field_neighbourhoods && h >= 0 &&
      h < sampler.fieldCount() && sampler.insideBox(h, x)) {
    const FieldNeighbourhoods& nb = neighbourhoods_;
    const int* list = nb.entries.data() + nb.offsets[h];
    const int count = nb.offsets[h + 1] - nb.offsets[h];
    const Eigen::Vector4f sample = sampler.sampleSubset(
        x, list, count, FieldNeighbourhoods::kFieldMask, per_field);
    if (home) {
      *home = HomeSamples();
      home->home = per_field[h];
      for (int n = 0; n < count; ++n) {
        const int i = list[n] & FieldNeighbourhoods::kFieldMask;
        if (!(list[n] & FieldNeighbourhoods::kPartner) &&
            per_field[i][0] > home->other[0])
          home->other = per_field[i];
      }
    }
    return sample;
  }
  const Eigen::Vector4f sample = sampler.sample(x, per_field);
  if (home) *home = homeSamples(*mesh_, partners_.data(), v, per_field);
  return sample;
}

bool CpuSurfaceTracking::onShiftingRestCrease(int v,
                                              const HomeSamples& home) const {
  const int crease = mesh_->rest_crease[v];
  return crease >= 0 && crease_shifts_[crease] &&
         prev_(v, 3) != ISK_GRADIENT_TO_CONTACT &&
         home.home[0] >= homeMinimum(*mesh_, v, options_);
}

void CpuSurfaceTracking::project(int steps) {
  checkBegun("project");
  const auto start = std::chrono::steady_clock::now();
  const ComposedFieldSampler sampler(*fields_, skinning_, composition_);
  const float cos_contact = std::cos(options_.contact_angle_degrees *
                                     static_cast<float>(M_PI) / 180.f);
  const int n = mesh_->vertexCount();
  std::vector<Eigen::Vector4f> per_field(std::max(fields_->fieldCount(), 1));
  for (int v = 0; v < n; ++v) {
    const float max_step = lengths_.max_step[v];
    const float min_gradient = lengths_.min_gradient[v];
    for (int s = 0; s < steps; ++s) {
      if (states_[v] != TrackState::kMarching) break;
      Eigen::Vector3f x = positions_.row(v).transpose();
      HomeSamples home;
      const Eigen::Vector4f sample =
          sampleAt(sampler, v, x, per_field.data(), &home);
      const float f = sample[0];
      const Eigen::Vector3f g = sample.tail<3>();
      const float g_len = g.norm();
      if (!(f > 0.f) || !(g_len > min_gradient)) {
        states_[v] = TrackState::kLost;
        break;
      }
      const float iso = mesh_->iso_values[v];
      float entered = 0.f;  // how far another part's field exceeds home
      if (options_.home_contact && mesh_->home_field[v] >= 0) {
        entered = home.other[0] - home.home[0] - mesh_->home_margin[v];
        if (onShiftingRestCrease(v, home)) entered = 0.f;
        Eigen::Vector4f frame = relax_frames_.row(v).transpose();
        const int march = marchToContact(
            &x, &prev_(v, 3), &frame, f, iso, home, entered,
            homeFloor(*mesh_, v, options_), homeMinimum(*mesh_, v, options_),
            options_, max_step, min_gradient);
        if (march == kContactMarchStepped) {
          relax_frames_.row(v) = frame.transpose();
          positions_.row(v) = x.transpose();
          continue;
        }
        if (march != kContactMarchNone) {
          states_[v] = static_cast<TrackState>(march);
          break;
        }
      }
      const Eigen::Vector3f unit = g / g_len;
      if (contactStop(unit, prev_.row(v).transpose(), cos_contact)) {
        states_[v] = TrackState::kContact;
        break;
      }
      prev_.row(v) << unit.x(), unit.y(), unit.z(), ISK_GRADIENT_STEP;
      const float d = iso - f;
      if (std::abs(d) < options_.tolerance) {
        // On another part's surface: a crease between parts, smoothed
        // like a contact.
        states_[v] = entered > options_.tolerance ? TrackState::kCrease
                                                  : TrackState::kConverged;
        break;
      }
      relax_frames_.row(v) << f - iso, unit.x(), unit.y(), unit.z();
      x = newtonStep(x, unit, d, g_len, options_.sigma, max_step);
      positions_.row(v) = x.transpose();
    }
  }
  times_.projection_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::relax() {
  checkBegun("relax");
  const auto start = std::chrono::steady_clock::now();
  const int n = mesh_->vertexCount();
  scratch_ = positions_;
  const OneRings& rings = mesh_->rings;
  const RelaxationWeights& relaxation = mesh_->relaxation;
  const bool skinned_ring = options_.skinned_ring_relaxation;
  for (int v = 0; v < n; ++v) {
    if (states_[v] != TrackState::kMarching ||
        relaxation.rules[v] == RelaxationRule::kFixed)
      continue;
    // The surface the vertex marches to (its iso-surface, or the contact
    // surface while it marches to a contact) as its last projection step
    // sampled it: signed distance and unit normal.
    const Eigen::Vector4f frame = relax_frames_.row(v).transpose();
    const Eigen::Vector3f unit = frame.tail<3>();
    if (!(unit.squaredNorm() > 0.f)) continue;  // no step this frame
    const Eigen::Vector3f x = positions_.row(v).transpose();
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    Eigen::Vector3f skinned_centroid = Eigen::Vector3f::Zero();
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i) {
      const int j = rings.neighbours[i];
      centroid += relaxation.weights[i] * positions_.row(j).transpose();
      if (skinned_ring)
        skinned_centroid += relaxation.weights[i] * skinned_.row(j).transpose();
    }
    if (skinned_ring)
      centroid -=
          skinnedRingOffset(skinned_centroid - skinned_.row(v).transpose(),
                            fallback_normals_.row(v).transpose());
    scratch_.row(v) = tangentialRelaxation(x, centroid, frame).transpose();
  }
  positions_.swap(scratch_);
  times_.relaxation_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::smooth() {
  checkBegun("smooth");
  const auto start = std::chrono::steady_clock::now();
  const int n = mesh_->vertexCount();
  const OneRings& rings = mesh_->rings;
  // The crease gate's inputs at v, over positions p (the current or the
  // skinned ones): the closed ring's vector area and the near centroid's
  // offset from v.
  auto ringArea = [&](const Matrix3Xf& p, int v) {
    const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
    const Eigen::Vector3f x = p.row(v).transpose();
    Eigen::Vector3f area = Eigen::Vector3f::Zero();
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t j = i + 1 < end ? i + 1 : begin;
      area += (p.row(rings.neighbours[i]).transpose() - x)
                  .cross(p.row(rings.neighbours[j]).transpose() - x);
    }
    return area;
  };
  auto nearShift = [&](const Matrix3Xf& p, int v) {
    const float radius = lengths_.smoothing_radius[v];
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    int near = 0;
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i) {
      if (!(mesh_->ring_lengths[i] <= radius)) continue;
      centroid += p.row(rings.neighbours[i]).transpose();
      ++near;
    }
    centroid /= static_cast<float>(std::max(near, 1));
    return Eigen::Vector3f(centroid - p.row(v).transpose());
  };
  auto creaseSource = [&](int v) {
    if (!options_.crease_gate || rings.kinds[v] != RingKind::kClosed)
      return 1.f;
    const float radius = lengths_.smoothing_radius[v];
    float length = 0.f;
    int near = 0;
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
      if (mesh_->ring_lengths[i] <= radius) {
        length += mesh_->ring_lengths[i];
        ++near;
      }
    if (near == 0) return 1.f;
    // The largest stretch of a spoke beyond its skinned length, in rest
    // lengths.
    float stretch = 0.f;
    const Eigen::Vector3f x = positions_.row(v).transpose();
    const Eigen::Vector3f sx = skinned_.row(v).transpose();
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i) {
      const int j = rings.neighbours[i];
      const float now = (positions_.row(j).transpose() - x).norm();
      const float skinned = (skinned_.row(j).transpose() - sx).norm();
      stretch = std::max(stretch, (now - skinned) / mesh_->ring_lengths[i]);
    }
    return creaseGate(ringArea(positions_, v), ringArea(skinned_, v),
                      nearShift(positions_, v), nearShift(skinned_, v),
                      length / static_cast<float>(near), stretch);
  };
  beta_.assign(2 * static_cast<size_t>(n), 0.f);
  crease_sources_.assign(n, 0.f);
  for (int v = 0; v < n; ++v) {
    beta_[2 * v] = states_[v] == TrackState::kContact ? 1.f : 0.f;
    if (states_[v] == TrackState::kCrease) crease_sources_[v] = creaseSource(v);
    beta_[2 * v + 1] = crease_sources_[v];
  }
  const int diffusions =
      std::max(options_.beta_diffusion, options_.crease_diffusion);
  for (int k = 0; k < diffusions; ++k) {
    const bool channel[2] = {k < options_.beta_diffusion,
                             k < options_.crease_diffusion};
    beta_scratch_ = beta_;
    for (int v = 0; v < n; ++v) {
      if (rings.kinds[v] == RingKind::kDuplicate) continue;
      const float radius = lengths_.smoothing_radius[v];
      float count = 1.f;
      for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
        count += mesh_->ring_lengths[i] <= radius ? 1.f : 0.f;
      for (int c = 0; c < 2; ++c) {
        // Contacts stay at 1, creases at their source value or more.
        if (!channel[c] || (c == 0 && states_[v] == TrackState::kContact))
          continue;
        float sum = beta_[2 * v + c];
        for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
          if (mesh_->ring_lengths[i] <= radius)
            sum += beta_[2 * static_cast<size_t>(rings.neighbours[i]) + c];
        beta_scratch_[2 * v + c] =
            c == 1 ? std::max(sum / count, crease_sources_[v]) : sum / count;
      }
    }
    beta_.swap(beta_scratch_);
  }
  const int steps = std::max(options_.smoothing_steps, options_.crease_steps);
  for (int k = 0; k < steps; ++k) {
    scratch_ = positions_;
    for (int v = 0; v < n; ++v) {
      const float b = k < options_.smoothing_steps ? beta_[2 * v] : 0.f;
      const float c = k < options_.crease_steps ? beta_[2 * v + 1] : 0.f;
      if (!(b > 0.f || c > 0.f) ||
          mesh_->relaxation.rules[v] == RelaxationRule::kFixed)
        continue;
      const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
      const float radius = lengths_.smoothing_radius[v];
      const Eigen::Vector3f x = positions_.row(v).transpose();
      Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
      int near = 0;
      for (uint32_t i = begin; i < end; ++i) {
        if (!(mesh_->ring_lengths[i] <= radius)) continue;
        centroid += positions_.row(rings.neighbours[i]).transpose();
        ++near;
      }
      if (near == 0) continue;
      centroid /= static_cast<float>(near);
      const Eigen::Vector3f d = centroid - x;
      Eigen::Vector3f tangential = Eigen::Vector3f::Zero();
      if (c > 0.f && rings.kinds[v] == RingKind::kClosed) {
        // The ring's area-weighted normal at the current positions.
        Eigen::Vector3f normal = ringArea(positions_, v);
        const float length = normal.norm();
        if (length > 0.f && std::isfinite(length)) {  // inf: no direction
          normal /= length;
          tangential = d - d.dot(normal) * normal;
        }
      }
      scratch_.row(v) = smoothingStep(x, d, tangential, b, c).transpose();
    }
    positions_.swap(scratch_);
  }
  times_.smoothing_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::frameFolds() {
  const OneRings& rings = mesh_->rings;
  const TriangleMatrix& triangles = mesh_->triangles;
  fold_frames_.resize(triangles.rows());
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    int r[3];
    for (int c = 0; c < 3; ++c) r[c] = rings.representative[triangles(t, c)];
    fold_frames_[t] = foldFrame(
        skinned_.row(r[0]).transpose(), skinned_.row(r[1]).transpose(),
        skinned_.row(r[2]).transpose(),
        (fallback_normals_.row(r[0]) + fallback_normals_.row(r[1]) +
         fallback_normals_.row(r[2]))
            .transpose());
  }
}

void CpuSurfaceTracking::weighFolds(const Matrix3Xf& offsets) {
  const int n = mesh_->vertexCount();
  const OneRings& rings = mesh_->rings;
  const TriangleMatrix& triangles = mesh_->triangles;
  fold_weights_.assign(n, 0.f);
  folded_triangles_ = 0;
  const float tilt_cosine = tiltGuardCosine(options_);
  const float tilt_scale = tiltGuardScale(options_);
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    int r[3];
    Eigen::Vector3f p[3];
    for (int c = 0; c < 3; ++c) {
      r[c] = rings.representative[triangles(t, c)];
      p[c] = (skinned_.row(r[c]) + offsets.row(r[c])).transpose();
    }
    const Eigen::Vector3f now = triangleNormal(p[0], p[1], p[2]);
    float weight = foldWeight(now, fold_frames_[t]);
    // A tilted triangle weighs as a fold whose weight gives its edges the
    // tilt strain limit (the limit falls linearly with the weight).
    if (tilt_scale > 0.f)
      weight = std::max(
          weight, tilt_scale * tiltWeight(now, fold_frames_[t], tilt_cosine));
    if (!(weight > 0.f)) continue;
    ++folded_triangles_;
    for (const int c : r) fold_weights_[c] = std::max(fold_weights_[c], weight);
  }
  // fold_rings rings around the corners (one-rings are symmetric): the
  // largest weight of the vertex and its ring.
  for (int k = 0; k < options_.fold_rings; ++k) {
    fold_scratch_ = fold_weights_;
    for (int v = 0; v < n; ++v)
      for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
        fold_scratch_[v] =
            std::max(fold_scratch_[v], fold_weights_[rings.neighbours[i]]);
    fold_weights_.swap(fold_scratch_);
  }
}

void CpuSurfaceTracking::limitStrain() {
  checkBegun("limitStrain");
  limitStrainSteps(options_.strain_limit_steps);
}

void CpuSurfaceTracking::restoreVolumeAgain() {
  checkBegun("restoreVolumeAgain");
  if (!restoresVolumeAgain(options_)) return;
  // The inward moves only: the contact bulge would push the band beside the
  // contacts out again, which the short limit after it does not even out.
  // The bulge's band, weights and fractions stay restoreVolume()'s (as on
  // the device).
  std::vector<float> band = bulge_band_, weights = bulge_weights_,
                     fractions = bulge_fractions_;
  restoreVolumeWith(/*contact_bulge=*/false);
  bulge_band_ = std::move(band);
  bulge_weights_ = std::move(weights);
  bulge_fractions_ = std::move(fractions);
  limitStrainSteps(options_.restore_again_steps);
}

void CpuSurfaceTracking::limitStrainSteps(int steps) {
  const auto start = std::chrono::steady_clock::now();
  const int n = mesh_->vertexCount();
  const OneRings& rings = mesh_->rings;
  fold_weights_.assign(n, 0.f);
  folded_triangles_ = 0;
  if (steps > 0) {
    Matrix3Xf offsets = positions_ - skinned_;
    Matrix3Xf next = offsets;
    if (options_.fold_guard) frameFolds();
    for (int k = 0; k < steps; ++k) {
      if (options_.fold_guard && k % options_.fold_check_steps == 0)
        weighFolds(offsets);
      for (int v = 0; v < n; ++v) {
        if (!(mesh_->iso_values[v] > 0) || rings.representative[v] != v)
          continue;
        const uint32_t begin = rings.offsets[v];
        auto neighbour_offset = [&](int i) -> Eigen::Vector3f {
          return offsets.row(rings.neighbours[begin + i]).transpose();
        };
        auto rest_length = [&](int i) {
          return mesh_->ring_lengths[begin + i];
        };
        const float fold_v = fold_weights_[v];
        auto limit = [&](int i) {
          const float w =
              std::max(fold_v, fold_weights_[rings.neighbours[begin + i]]);
          return options_.strain_limit +
                 w * (options_.fold_strain_limit - options_.strain_limit);
        };
        bool moved = false;
        next.row(v) =
            strainLimitStep(offsets.row(v).transpose(),
                            static_cast<int>(rings.offsets[v + 1] - begin),
                            neighbour_offset, rest_length, limit, &moved)
                .transpose();
      }
      offsets.swap(next);
    }
    // s + d where the steps changed the offset, x itself where they did not
    // (bit for bit).
    for (int v = 0; v < n; ++v) {
      const Eigen::RowVector3f d0 = positions_.row(v) - skinned_.row(v);
      if (offsets.row(v) != d0)
        positions_.row(v) = skinned_.row(v) + offsets.row(v);
    }
  }
  times_.strain_limit_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::finish() {
  checkBegun("finish");
  const auto start = std::chrono::steady_clock::now();
  const int n = mesh_->vertexCount();
  for (int v = 0; v < n; ++v) {
    const int r = mesh_->rings.representative[v];
    if (r != v) positions_.row(v) = positions_.row(r);
  }
  VertexNormalsJob job;
  job.positions = &positions_;
  job.triangles = &mesh_->triangles;
  job.adjacency = &mesh_->normal_adjacency;
  job.fallback_normals = &fallback_normals_;
  job.out_normals = &normals_;
  job.run();
  times_.normals_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::translate(const Eigen::Vector3f& offset) {
  checkBegun("translate");
  const auto start = std::chrono::steady_clock::now();
  positions_.rowwise() += offset.transpose();
  times_.normals_ms += millisecondsSince(start);
}

void CpuSurfaceTracking::run(const TransformList& skinning,
                             const Matrix3Xf& skinned_positions,
                             const Matrix3Xf& skinned_normals,
                             const Matrix3Xf* start) {
  begin(skinning, skinned_positions, skinned_normals, start);
  for (int r = 0; r < options_.rounds; ++r) {
    project(options_.projection_steps);
    if (options_.relaxation) relax();
  }
  smooth();
  restoreVolume();
  limitStrain();
  restoreVolumeAgain();
  finish();
}

void CpuSurfaceTracking::restoreVolume() {
  checkBegun("restoreVolume");
  restoreVolumeWith(/*contact_bulge=*/true);
}

void CpuSurfaceTracking::restoreVolumeWith(bool contact_bulge) {
  const TrackingMesh::VolumeGroups& groups = mesh_->volume_groups;
  const int group_count = groups.groupCount();
  const int n = mesh_->vertexCount();
  volume_fractions_.assign(group_count, 0.f);
  bulge_fractions_.assign(group_count, 0.f);
  restore_weights_.assign(n, 0.f);
  bulge_band_.assign(n, 0.f);
  bulge_weights_.assign(n, 0.f);
  if (!(options_.volume_restore > 0.f) || group_count == 0 ||
      static_cast<int>(groups.vertex_group.size()) != n ||
      static_cast<int>(groups.vertex_area.size()) != n ||
      static_cast<int>(groups.normal_sign.size()) != n)
    return;
  const auto start = std::chrono::steady_clock::now();
  const OneRings& rings = mesh_->rings;
  // Each group's volume now, about its first corner.
  auto groupVolume = [&](int g) {
    const int first = groups.triangle_offsets[g];
    const Eigen::Vector3f c0 =
        positions_.row(groups.corners[3 * static_cast<size_t>(first)])
            .transpose();
    double volume = 0;
    for (int t = first; t < groups.triangle_offsets[g + 1]; ++t) {
      const int* c = &groups.corners[3 * static_cast<size_t>(t)];
      volume += tripleProduct(c0, positions_.row(c[0]).transpose(),
                              positions_.row(c[1]).transpose(),
                              positions_.row(c[2]).transpose());
    }
    return volume / 6;
  };
  std::vector<double> missing(group_count), weighted(group_count, 0.0),
      bulge_weighted(group_count, 0.0);
  for (int g = 0; g < group_count; ++g)
    missing[g] = groups.rest_volume[g] - groupVolume(g);
  const bool near_rows = static_cast<int>(groups.near_other.size()) == n;
  const bool bulge = contact_bulge && options_.contact_bulge > 0.f &&
                     options_.contact_bulge_steps > 0;
  // The inward moves outside contacts and creases and their weighted sums.
  for (int v = 0; v < n; ++v) {
    const int g = groups.vertex_group[v];
    if (g < 0) continue;
    restore_weights_[v] = volumeRestoreWeight(
        states_[v], beta_[2 * v], beta_[2 * v + 1],
        positions_.row(v).transpose(), skinned_.row(v).transpose(),
        fallback_normals_.row(v).transpose(), groups.normal_sign[v]);
    const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
    if (restore_weights_[v] > 0.f) {
      // Faded by the share of its ring that does not move (a contact, a
      // crease, a part left alone): no shear against a border that stays.
      int moving = 0;
      for (uint32_t i = begin; i < end; ++i) {
        const int u = rings.neighbours[i];
        moving += states_[u] == TrackState::kConverged &&
                  !(beta_[2 * u] > 0.f) && groups.vertex_group[u] >= 0;
      }
      if (end > begin)
        restore_weights_[v] *=
            static_cast<float>(moving) / static_cast<float>(end - begin);
    }
    weighted[g] += restore_weights_[v] * groups.vertex_area[v];
  }
  bool bulge_needed = false;
  for (int g = 0; g < group_count && bulge && !bulge_needed; ++g)
    bulge_needed = contactBulgeMissing(missing[g], weighted[g],
                                       options_.volume_restore) > 0.0;
  if (bulge_needed) {
    // The band around the contacts, one ring per step (Jacobi).
    for (int v = 0; v < n; ++v)
      bulge_band_[v] = states_[v] == TrackState::kContact ? 1.f : 0.f;
    std::vector<float> next(n);
    for (int k = 0; k < options_.contact_bulge_steps; ++k) {
      for (int v = 0; v < n; ++v) {
        const uint32_t begin = rings.offsets[v];
        next[v] = contactBandStep(
            bulge_band_[v], static_cast<int>(rings.offsets[v + 1] - begin),
            [&](int i) { return bulge_band_[rings.neighbours[begin + i]]; },
            [&](int i) { return mesh_->ring_lengths[begin + i]; },
            lengths_.bulge_reach[v]);
      }
      bulge_band_.swap(next);
    }
    // The bulge weights, each probed for clearance, and their weighted sums.
    const ComposedFieldSampler sampler(*fields_, skinning_, composition_);
    std::vector<Eigen::Vector4f> per_field(std::max(fields_->fieldCount(), 1));
    for (int v = 0; v < n; ++v) {
      const int g = groups.vertex_group[v];
      const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
      if (g < 0 || end == begin) continue;
      float length = 0.f;
      for (uint32_t i = begin; i < end; ++i) length += mesh_->ring_lengths[i];
      const float mean_length = length / static_cast<float>(end - begin);
      bulge_weights_[v] = contactBulgeWeight(
          states_[v], beta_[2 * v], beta_[2 * v + 1],
          near_rows && groups.near_other[v], bulge_band_[v], mean_length);
      if (bulge_weights_[v] > 0.f && options_.contact_bulge_clearance > 0.f) {
        // The probe: the largest push times the clearance, out along it.
        const Eigen::Vector3f probe = volumeRestoreStep(
            positions_.row(v).transpose(), fallback_normals_.row(v).transpose(),
            groups.normal_sign[v],
            options_.contact_bulge_clearance * options_.contact_bulge *
                mean_length);
        bulge_weights_[v] *= contactBulgeClearance(
            sampler.sample(probe, per_field.data())[0], mesh_->iso_values[v]);
      }
      bulge_weighted[g] += bulge_weights_[v] * groups.vertex_area[v];
    }
  }
  for (int g = 0; g < group_count; ++g) {
    volume_fractions_[g] =
        volumeRestoreFraction(missing[g], weighted[g], options_.volume_restore);
    bulge_fractions_[g] =
        contactBulgeFraction(missing[g], weighted[g], options_.volume_restore,
                             bulge_weighted[g], options_.contact_bulge);
  }
  auto step = [&](const std::vector<float>& fractions,
                  const std::vector<float>& factors) {
    for (int v = 0; v < n; ++v) {
      const int g = groups.vertex_group[v];
      if (g < 0 || !(restore_weights_[v] > 0.f || bulge_weights_[v] > 0.f))
        continue;
      const float limit = volumeRestoreLimit(near_rows && groups.near_other[v],
                                             options_.volume_restore);
      const float distance =
          volumeRestoreDistance(fractions[g], factors[g], limit,
                                restore_weights_[v]) +
          volumeRestoreDistance(bulge_fractions_[g], factors[g],
                                options_.contact_bulge, bulge_weights_[v]);
      positions_.row(v) =
          volumeRestoreStep(positions_.row(v).transpose(),
                            fallback_normals_.row(v).transpose(),
                            groups.normal_sign[v], distance)
              .transpose();
    }
  };
  const std::vector<float> first = volume_fractions_;
  step(first, std::vector<float>(group_count, 1.f));
  // The secant step back where a group went past its rest volume.
  std::vector<float> back(group_count, 0.f);
  for (int g = 0; g < group_count; ++g) {
    const double gained = groupVolume(g) - (groups.rest_volume[g] - missing[g]);
    volume_fractions_[g] =
        volumeRestoreCorrection(missing[g], gained, first[g]);
    back[g] = volumeRestoreBackFactor(first[g], volume_fractions_[g],
                                      bulge_fractions_[g], missing[g], gained);
  }
  step(first, back);
  times_.volume_ms += millisecondsSince(start);
}

}  // namespace isk
