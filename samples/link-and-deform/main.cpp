// link-and-deform: the smallest complete isk program. It loads a rig (or
// builds the procedural cylinder), builds the implicit skinner once, deforms
// five frames of the rig's first clip on the default OpenCL device, prints
// one line per frame and writes the last frame to link-and-deform.obj.
//
//   isk-link-and-deform [RIG_FILE]   (glTF/GLB, FBX, COLLADA, .x, ...)
#include <cstdio>
#include <exception>

#include "isk/cl/runtime.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/export.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"

int main(int argc, char** argv) try {
  const isk::Rig rig =
      argc > 1 ? isk::importRig(argv[1]) : isk::makeBuiltinRig("cylinder");
  auto context = isk::ClContext::create();  // $ISK_DEVICE, a GPU, else a CPU
  std::printf("%s: %d vertices, %d joints, on %s\n", rig.source.c_str(),
              rig.mesh.vertexCount(), rig.skeleton.jointCount(),
              context->info().describe().c_str());

  isk::ImplicitSkinner skinner(context, rig);  // builds the fields: seconds
  const isk::AnimationClip& clip = rig.clips.at(0);
  isk::Matrix3Xf positions, normals;  // #V by 3
  const int frames = 5;
  for (int i = 0; i < frames; ++i) {
    const double t = clip.start + clip.duration * i / (frames - 1);  // seconds
    const isk::TransformList locals = clip.sampleLocal(rig.skeleton, t);
    skinner.run(isk::skinningTransforms(
        rig.skeleton, isk::globalTransforms(rig.skeleton, locals)));
    skinner.readPositions(positions);
    if (!positions.allFinite()) {
      std::fprintf(stderr, "frame %d: non-finite positions\n", i);
      return 1;
    }
    const float moved =
        (positions - rig.mesh.positions).rowwise().norm().maxCoeff();
    std::printf("frame %d  t %.3f s  max displacement %.6g  contacts %d\n", i,
                t, moved, skinner.contactCount());
  }
  skinner.readNormals(normals);
  isk::writeMesh("link-and-deform.obj", isk::MeshFormat::kObj, positions,
                 &normals, rig.mesh.triangles);
  std::printf("wrote link-and-deform.obj\n");
  return 0;
} catch (const std::exception& e) {  // isk::Error names what failed and where
  std::fprintf(stderr, "link-and-deform: %s\n", e.what());
  return 1;
}
