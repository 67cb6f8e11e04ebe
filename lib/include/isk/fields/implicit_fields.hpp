// Offline builder of a character's implicit fields (Vaillant et al. 2013,
// section 4.1): partition -> samples -> HRBF fits -> baked grids -> per-vertex
// iso values. Editable stages are exposed (samples can be edited through
// `edit_samples`); the result is immutable data ready to upload.
//
// Bad parts do not stop the build: a part whose samples fall under 4 after
// culling is re-sampled without culling, then from its vertices; a part that
// still has fewer than 4 points gets no field. Each case leaves a warning
// naming the joint.
#pragma once

#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "isk/fields/bone_field.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/fields/bone_samples.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/field_grid.hpp"
#include "isk/rig/rig.hpp"

namespace isk {

// Rigid pieces (not in the paper; docs/algorithm.md, *Rigid pieces*): a
// connected component of the mesh welded by position whose every vertex is
// bound to one and the same joint (weight kRigidPieceWeight or more) moves
// rigidly with it: skinning puts it exactly where it belongs, and the march
// could only bend it (a robot's armour plates, a mannequin's segments).
enum class RigidPieces {
  kAuto,     // rigid when rigid pieces hold kRigidCharacterShare or more of
             // the mesh's vertices (a character of rigid parts); else tracked
  kRigid,    // always left on skinning (untracked)
  kTracked,  // tracked like the skin, as the paper does
};
constexpr float kRigidPieceWeight = 0.999f;
constexpr float kRigidCharacterShare = 0.5f;
// "auto", "rigid", "tracked".
const char* rigidPiecesName(RigidPieces mode);
// Parses rigidPiecesName's names; false for anything else.
bool parseRigidPieces(const std::string& name, RigidPieces* mode);
// The vertices of `rig`'s rigid pieces, ascending (whatever the mode).
std::vector<int> rigidPieceVertices(const Rig& rig);

// Everything buildImplicitFields can be told; the defaults are the paper's.
struct ImplicitFieldsOptions {
  BoneSamplingOptions sampling;  // Poisson-disk samples, culling, closure
  int grid_resolution = 32;      // nodes per axis of each baked field, 2..256
  // kHalf: the grids are rounded to half precision after baking (or loading
  // from the cache, which keeps them in float) and the iso values are taken
  // from the rounded grids (useHalfPrecisionGrids).
  GridPrecision grid_precision = GridPrecision::kFloat;
  // Operators per joint (union by default); the iso values are taken in
  // the composed field.
  CompositionOptions composition;
  int threads = 0;  // fitting and baking threads; 0: all hardware threads
  // Called after sampling, before fitting, with the samples of every bone
  // that has a part (joint order): add or remove points here.
  std::function<void(std::vector<BoneSamples>&)> edit_samples;
  // Per-joint Poisson-disk targets by joint name (replace
  // sampling.target_samples for that joint's part; 1..100000).
  std::map<std::string, int> joint_samples;
  // Joints whose parts stay where geometric skinning puts them, by name:
  // their vertices get iso value 0 (untracked), their fields still meet
  // the other parts. For parts the fields cannot hold (a wing's membrane a
  // few triangles thick, a strap): docs/algorithm.md, *Untracked joints*.
  std::set<std::string> untracked_joints;
  // Whether the rigid pieces (see RigidPieces) stay on skinning.
  RigidPieces rigid_pieces = RigidPieces::kAuto;
  // On-disk cache of the built fields (isk/fields/field_cache.hpp): when true,
  // the samples, fits and baked grids are loaded from `cache_folder` (empty:
  // operatorTableCacheFolder(), i.e. $ISK_CACHE_DIR, "off" disabling it)
  // when a valid file for this rig and these options is there, else built
  // and written there. A stale file (mesh, weights or skeleton changed) or a
  // corrupt one is reported (cache_note and `warnings`) and rebuilt, never
  // used. Ignored when `edit_samples` is set (a function cannot be part of
  // the key).
  bool cache = false;
  std::string cache_folder;
  // Progress: `stage` is "partition", "loading" (from the cache, which then
  // replaces sampling, fitting and baking), "sampling", "fitting", "baking",
  // "operators" (tables baked once per process) or "iso values"; `fraction`
  // grows from 0 to 1 within a stage. Called from the calling thread.
  std::function<void(const char* stage, float fraction)> progress;
};

// Milliseconds spent in each stage of buildImplicitFields.
struct ImplicitFieldsTimes {
  double partition_ms = 0, sampling_ms = 0, fitting_ms = 0, baking_ms = 0,
         operators_ms = 0, iso_ms = 0;
  // Sum of the stages.
  double total() const {
    return partition_ms + sampling_ms + fitting_ms + baking_ms + operators_ms +
           iso_ms;
  }
};

// Where buildImplicitFields got the samples, fits and grids.
enum class FieldCacheOrigin {
  kOff,      // no cache asked for, no cache folder, or edit_samples set
  kBuilt,    // no cache file yet: built and written
  kLoaded,   // a valid cache file
  kRebuilt,  // the file was stale or corrupt: reported, rebuilt, rewritten
};
// "off", "built", "loaded", "rebuilt".
const char* fieldCacheOriginName(FieldCacheOrigin origin);

// A character's implicit fields, every stage's result. "Per field" arrays
// have one entry per fitted field, in joint order: the joints with a part
// (partition.field_joints) less those whose fit failed (a warning names
// them), so field i belongs to fields[i].joint (= grids.grids[i].joint), and
// joint j's field is grids.field_of_joint[j] -- not partition.field_joints[i].
struct ImplicitFields {
  BonePartition partition;
  std::vector<BoneSamples> samples;  // per field
  std::vector<BoneField> fields;     // per field, joint order (analytic)
  FieldGridSet grids;                // per field (baked: what is evaluated)
  Composition composition;           // the operator of each joint pair
  // #V: each vertex's composed field value at the bind pose, the iso value
  // tracking brings it back to; 0 (untracked) outside every support, on
  // the parts of options.untracked_joints and on the rigid pieces left on
  // skinning.
  std::vector<float> iso_values;
  std::vector<int> outside_vertices;  // vertices outside every support
  // The vertices of untracked_joints' parts and of the rigid pieces left
  // on skinning (ascending; iso value 0).
  std::vector<int> untracked_vertices;
  // Of those, the rigid pieces' (ascending; empty unless options.
  // rigid_pieces left them on skinning).
  std::vector<int> rigid_piece_vertices;
  // One sentence each: empty or degenerate parts, re-sampled or dropped
  // fields, regularised fits, named joints without a pair, a cache file
  // that was unusable or could not be written. The library prints nothing:
  // showing them is the application's choice.
  std::vector<std::string> warnings;
  ImplicitFieldsTimes times;
  FieldCacheOrigin cache_origin = FieldCacheOrigin::kOff;
  std::string cache_file;  // the cache file read or written, if any
  std::string cache_note;  // why a cache file was not used (kRebuilt)
};

// Validates `rig` and options (isk::Error kInvalidArgument, naming what is
// wrong) and builds its fields. Seconds for a character of a few thousand
// vertices; deterministic for the same rig and options.
ImplicitFields buildImplicitFields(const Rig& rig,
                                   const ImplicitFieldsOptions& options = {});

// Whether `fields` can skin `rig`: one iso value per vertex and every
// field's joint in its skeleton; the reason gives the counts ("built for
// another rig?").
Validation fieldsFitRig(const ImplicitFields& fields, const Rig& rig);

// Turns `fields` (built for `rig`) into half-precision ones without fitting
// again: rounds the grids (roundGridsToHalf: an OpenCL skinner then stores
// 2 bytes per channel instead of 4) and takes the iso values and the
// outside vertices again from the rounded grids, so that the rest pose
// still lies on its iso-surfaces. The frames move by a small fraction of
// the mesh's size (docs/performance.md). Throws what roundGridsToHalf throws,
// and isk::Error(kInvalidArgument) when `fields` do not fit `rig`'s mesh;
// `fields` are unchanged then. Does nothing to fields already in half.
void useHalfPrecisionGrids(ImplicitFields& fields, const Rig& rig);

}  // namespace isk
