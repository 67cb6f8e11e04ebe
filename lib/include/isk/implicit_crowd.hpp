// Several characters, each instanced any number of times, skinned together
// (Vaillant et al. 2013, implicit skinning, as isk::ImplicitSkinner does it
// for one): every stage of a frame is one kernel launch over the vertices of
// all instances, so a crowd of small characters pays the launches, the
// waits and the read-back once per frame instead of once per character.
//
//   isk::ImplicitCrowd crowd(context, rig, fields, 16);  // 16 instances
//   crowd.run(poses);              // 16 lists of #joints skinning transforms
//   crowd.readPositions(positions);  // (16 * #V) by 3: instance i's #V rows
//                                    // from row i * #V on
//
//   // Different characters: 8 of one, 4 of another, in that order.
//   isk::ImplicitCrowd mixed(context, {{&soldier, soldier_fields, 8},
//                                      {&horse, horse_fields, 4}});
//   mixed.run(poses);  // 12 lists, instance i's of jointCount(characterOf(i))
//   // instance i's rows: instanceFirstVertex(i) on, vertexCount(
//   // characterOf(i)) of them
//
// The instances share one scene: each one's skinning transforms place it
// (its root motion, or where the game puts it), in the scene's coordinates:
// keep the scene near its origin (a lone ImplicitSkinner computes about
// its pose's anchor instead, isk/rig/pose_anchor.hpp). Instances apart from
// each other are skinned exactly as an ImplicitSkinner computing in the
// same coordinates (anchor_pose off) skins each alone (tests
// check it, vertex by vertex, for one character and for several of
// different sizes: the tracking's lengths follow each vertex's own
// character, TrackingMesh::vertex_diagonals). Where two instances overlap,
// their fields compose like the parts of one character (the union of every
// field, eq. 3), so their skins stop at each other as parts of a body do
// (the contact of section 5) instead of passing through.
//
// Memory: the device holds each character's grids and operator tables
// once, shared by its instances, and per-vertex data per instance; the host
// builds the crowd's tracking mesh from one instance's per character (no
// welding across instances, whatever their rest positions). Characters in
// one crowd share one grid resolution and precision and one operator table
// resolution (fields built with the same ImplicitFieldsOptions do).
#pragma once

#include <memory>
#include <vector>

#include "isk/implicit_skinner.hpp"

namespace isk {

// `mesh` repeated `copies` times (instance i's vertices, triangles, rings
// and field indices shifted by i times theirs; its joints by i *
// joints_per_copy): the tracking mesh of a crowd. Throws
// isk::Error(kInvalidArgument) for copies < 1 or a result past int range.
TrackingMesh replicateTrackingMesh(const TrackingMesh& mesh, int copies,
                                   int joints_per_copy);

// The tracking meshes of several characters one after the other, each
// `copies` times (TrackingMeshCopies): copy by copy, vertices, triangles,
// rings and field indices shifted past the copies before, joints by
// joints_per_copy per copy. Where the parts differ in size (diagonal),
// vertex_diagonals holds each vertex's. Throws isk::Error(kInvalidArgument)
// for no parts, a null mesh, copies < 1 or a result past int range.
struct TrackingMeshCopies {
  const TrackingMesh* mesh = nullptr;
  int copies = 1;
  int joints_per_copy = 0;
};
TrackingMesh concatenateTrackingMeshes(
    const std::vector<TrackingMeshCopies>& parts);

// One character of a crowd: its rig (kept only while the crowd is built),
// fields built for it (buildImplicitFields; may be shared with other
// skinners) and how many instances of it the crowd skins.
struct CrowdCharacter {
  const Rig* rig = nullptr;
  std::shared_ptr<const ImplicitFields> fields;
  int instances = 1;
};

// Implicit skinning of the instances of one or several characters on an
// OpenCL device (see the top of this file). Not copyable; movable.
class ImplicitCrowd {
 public:
  // Builds the rig's fields with options.fields (once, for every instance)
  // and uploads. Throws isk::Error: kInvalidArgument naming what is wrong
  // in the rig, the options or the instance count, kOpenCl naming the
  // failing call.
  ImplicitCrowd(std::shared_ptr<ClContext> context, const Rig& rig,
                int instances, const ImplicitSkinnerOptions& options = {});
  // Uses fields built earlier for this rig (buildImplicitFields), shared
  // with other skinners.
  ImplicitCrowd(std::shared_ptr<ClContext> context, const Rig& rig,
                std::shared_ptr<const ImplicitFields> fields, int instances,
                const ImplicitSkinnerOptions& options = {});
  // Several characters: character c's instances follow character c - 1's
  // (instance numbers, pose lists and result rows alike). Throws
  // isk::Error: kInvalidArgument naming the character ("character 1: ...")
  // and what is wrong (its rig, fields built for another rig, an instance
  // count, a grid or table resolution other than the others'),
  // kOpenCl naming the failing call.
  ImplicitCrowd(std::shared_ptr<ClContext> context,
                const std::vector<CrowdCharacter>& characters,
                const ImplicitSkinnerOptions& options = {});
  ~ImplicitCrowd();
  ImplicitCrowd(ImplicitCrowd&&) noexcept;
  ImplicitCrowd& operator=(ImplicitCrowd&&) noexcept;

  // One frame of every instance: `skinning` holds #instances lists of
  // skinning transforms (isk/rig/pose.hpp), instance i's at [i], of
  // jointCount(characterOf(i)) transforms. Returns
  // when the device is done. Throws isk::Error(kInvalidArgument) naming the
  // instance and joint for a list of the wrong size or a non-finite
  // transform, and for the wrong number of lists.
  void run(const std::vector<TransformList>& skinning);

  // Blocking reads of the last frame: totalVertexCount() by 3, model space
  // (unit normals); instance i's vertex v at row instanceFirstVertex(i) + v
  // (i * #V + v for one character).
  void readPositions(Matrix3Xf& out);
  void readNormals(Matrix3Xf& out);
  // The same results on the device: totalVertexCount() * 3 packed floats.
  const cl::Buffer& positionsBuffer() const;
  const cl::Buffer& normalsBuffer() const;
  // Vertices of every instance stopped at a contact in the last frame.
  int contactCount();

  // Stage times of the last run() over the whole crowd (readback: of the
  // last reads).
  const ImplicitStageTimes& lastTimes() const;
  const TrackingMesh& trackingMesh() const;  // the crowd's
  ClSurfaceTracking& tracking();
  ClFieldEvaluation& fieldEvaluation();  // every instance's fields
  const ImplicitSkinnerOptions& options() const;
  int instanceCount() const;   // of every character
  int characterCount() const;  // 1 for the one-character constructors
  // Per character c (isk::Error kInvalidArgument for no such character):
  // its fields, and #V and #joints of one instance of it.
  const ImplicitFields& fields(int c = 0) const;
  int vertexCount(int c = 0) const;
  int jointCount(int c = 0) const;
  int totalVertexCount() const;  // rows of the results
  // Per instance i (isk::Error kInvalidArgument for no such instance): its
  // character, its first row in the results and its first joint in the
  // crowd's skeleton (the transforms of every instance one after the
  // other).
  int characterOf(int i) const;
  int instanceFirstVertex(int i) const;
  int instanceFirstJoint(int i) const;

 private:
  struct State;
  State& state(const char* what, bool needs_run) const;
  // c or i when it names a character or instance, else isk::Error.
  int character(const char* what, int c) const;
  int instance(const char* what, int i) const;
  std::unique_ptr<State> state_;
};

}  // namespace isk
