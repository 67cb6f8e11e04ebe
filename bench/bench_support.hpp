// Shared pieces of the benchmark suite: the models benchmarked, their rigs
// (cached), poses from their clips and the OpenCL context.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/rig.hpp"
#include "isk/types.hpp"

namespace isk::bench {

struct Model {
  std::string name;
  std::string file;  // in the data folder, empty for procedural
  int subdivision_levels = 0;
};

// The builtin arm, every shared asset, and CesiumMan subdivided to about 40k
// and 150k vertices.
const std::vector<Model>& models();
// Whether the model can run (asset models need the data folder).
bool available(const Model& model);
const Rig& rigOf(const Model& model);
// Frames of the rig's first clip at 30 fps (1 without a clip).
int clipFrameCount(const Rig& rig);
// Skinning transforms of frame `frame` (modulo clipFrameCount) of the rig's
// first clip.
TransformList poseAt(const Rig& rig, int64_t frame);
std::shared_ptr<ClContext> context();

void registerSkinningBenchmarks();
void registerFieldBenchmarks();
void registerImplicitBenchmarks();

}  // namespace isk::bench
