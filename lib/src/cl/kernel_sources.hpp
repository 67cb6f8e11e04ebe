// The kernels/*.cl files and the headers they include (kernels/*.h)
// embedded at build time (cmake/EmbedKernels.cmake).
#pragma once

#include <string_view>
#include <vector>

namespace isk::detail {

struct KernelSource {
  std::string_view name;  // a .cl file's name without .cl; a header's whole
                          // name ("abi.h")
  std::string_view text;
};

const std::vector<KernelSource>& embeddedKernelSources();

}  // namespace isk::detail
