// The kernels/*.cl files embedded at build time (cmake/EmbedKernels.cmake).
#pragma once

#include <string_view>
#include <vector>

namespace isk::detail {

struct KernelSource {
  std::string_view name;  // file name without .cl
  std::string_view text;
};

const std::vector<KernelSource>& embeddedKernelSources();

}  // namespace isk::detail
