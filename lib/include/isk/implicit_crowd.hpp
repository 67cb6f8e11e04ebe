// Several instances of one character skinned together (Vaillant et al. 2013,
// implicit skinning, as isk::ImplicitSkinner does it for one): every stage of
// a frame is one kernel launch over the vertices of all instances, so a crowd
// of small characters pays the launches, the waits and the read-back once per
// frame instead of once per character.
//
//   isk::ImplicitCrowd crowd(context, rig, fields, 16);  // 16 instances
//   crowd.run(poses);              // 16 lists of #joints skinning transforms
//   crowd.readPositions(positions);  // (16 * #V) by 3: instance i's #V rows
//                                    // from row i * #V on
//
// The instances share one scene: each one's skinning transforms place it
// (its root motion, or where the game puts it). Instances apart from each
// other are skinned exactly as an ImplicitSkinner skins each alone (tests
// check it, vertex by vertex); where two instances overlap, their fields
// compose like the parts of one character (the union of every field, eq. 3),
// so their skins stop at each other as parts of a body do (the contact of
// section 5) instead of passing through.
//
// Memory: the device holds the character's grids and operator tables once,
// shared by the instances, and #instances copies of its per-vertex data;
// the host builds the crowd's tracking mesh from one instance's (no welding
// across instances, whatever their rest positions).
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

// Implicit skinning of #instances instances of one character on an OpenCL
// device (see the top of this file). Not copyable; movable.
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
  ~ImplicitCrowd();
  ImplicitCrowd(ImplicitCrowd&&) noexcept;
  ImplicitCrowd& operator=(ImplicitCrowd&&) noexcept;

  // One frame of every instance: `skinning` holds #instances lists of
  // #joints skinning transforms (isk/pose.hpp), instance i's at [i]. Returns
  // when the device is done. Throws isk::Error(kInvalidArgument) naming the
  // instance and joint for a list of the wrong size or a non-finite
  // transform, and for the wrong number of lists.
  void run(const std::vector<TransformList>& skinning);

  // Blocking reads of the last frame: (#instances * #V) by 3, model space
  // (unit normals); instance i's vertex v at row i * #V + v.
  void readPositions(Matrix3Xf& out);
  void readNormals(Matrix3Xf& out);
  // The same results on the device: #instances * #V * 3 packed floats.
  const cl::Buffer& positionsBuffer() const;
  const cl::Buffer& normalsBuffer() const;
  // Vertices of every instance stopped at a contact in the last frame.
  int contactCount();

  // Stage times of the last run() over the whole crowd (readback: of the
  // last reads).
  const ImplicitStageTimes& lastTimes() const;
  const ImplicitFields& fields() const;      // one instance's
  const TrackingMesh& trackingMesh() const;  // the crowd's
  ClSurfaceTracking& tracking();
  ClFieldEvaluation& fieldEvaluation();  // every instance's fields
  const ImplicitSkinnerOptions& options() const;
  int instanceCount() const;
  int vertexCount() const;  // #V of one instance
  int jointCount() const;   // #joints of one instance

 private:
  struct State;
  State& state(const char* what, bool needs_run) const;
  std::unique_ptr<State> state_;
};

}  // namespace isk
