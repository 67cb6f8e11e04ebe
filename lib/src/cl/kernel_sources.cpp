#include "cl/kernel_sources.hpp"

#include <string>

#include "isk/cl/runtime.hpp"
#include "isk/core/error.hpp"

namespace isk {

std::vector<std::string> embeddedKernelNames() {
  std::vector<std::string> names;
  for (const auto& source : detail::embeddedKernelSources()) {
    // Headers are included by kernel files, not programs of their own.
    if (source.name.find('.') == std::string_view::npos)
      names.emplace_back(source.name);
  }
  return names;
}

std::string embeddedKernelSource(const std::string& kernel_file) {
  for (const auto& source : detail::embeddedKernelSources()) {
    if (source.name == kernel_file) return std::string(source.text);
  }
  const bool header = kernel_file.find('.') != std::string::npos;
  throw Error(
      ErrorCode::kInvalidArgument,
      "no embedded kernel file '" + kernel_file + (header ? "'" : ".cl'"));
}

}  // namespace isk
