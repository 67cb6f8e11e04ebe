#include "isk/rig/rig.hpp"

#include <cstdio>
#include <string>

#include "isk/tools/mesh_metrics.hpp"

namespace isk {

Validation Rig::validate() const {
  if (Validation v = mesh.validate(); !v) return v;
  if (Validation v = skeleton.validate(); !v) return v;
  Validation weights_ok =
      weights.validate(mesh.vertexCount(), skeleton.jointCount());
  if (!weights_ok) {
    // Name the vertex by the mesh it came from ("mesh 'Body' vertex 12").
    const std::string& reason = weights_ok.reason();
    int vertex = -1;
    if (std::sscanf(reason.c_str(), "vertex %d", &vertex) == 1) {
      const std::string rest = reason.substr(reason.find(' ', 7));
      return Validation::fail(mesh.describeVertex(vertex) + rest);
    }
    return weights_ok;
  }
  for (const AnimationClip& clip : clips) {
    if (Validation v = clip.validate(skeleton); !v) {
      return Validation::fail("clip '" + clip.name + "': " + v.reason());
    }
  }
  return Validation::ok();
}

int Rig::findClip(const std::string& name) const {
  for (size_t i = 0; i < clips.size(); ++i) {
    if (clips[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

float Rig::boundingBoxDiagonal() const {
  return isk::boundingBoxDiagonal(mesh.positions);
}

}  // namespace isk
