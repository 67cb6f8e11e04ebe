// How the device classes (ClSkinning, ClFieldEvaluation, ClSurfaceTracking)
// put host data on the device: one helper, so that every upload gets the
// same size checks and errors (ClContext::createBuffer: the allocation
// limit, the failing call, what was uploaded).
#pragma once

#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"

namespace isk::detail {

// n rounded up to a multiple of `multiple` (global work sizes).
inline size_t roundUp(size_t n, size_t multiple) {
  return (n + multiple - 1) / multiple * multiple;
}

// `count` elements of `data` copied into a new read-only buffer; `what`
// names it in errors. A zero-sized buffer is invalid in OpenCL: an empty
// array becomes one zero element. Adds the buffer's size to *bytes when
// given.
template <typename T>
cl::Buffer uploadReadOnly(const ClContext& context, const T* data, size_t count,
                          const std::string& what, size_t* bytes = nullptr) {
  std::vector<T> padded(data, data + count);
  if (padded.empty()) padded.resize(1);
  if (bytes) *bytes += padded.size() * sizeof(T);
  return context.createBuffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                              padded.size() * sizeof(T), padded.data(), what);
}

template <typename T>
cl::Buffer uploadReadOnly(const ClContext& context, const std::vector<T>& data,
                          const std::string& what, size_t* bytes = nullptr) {
  return uploadReadOnly(context, data.data(), data.size(), what, bytes);
}

}  // namespace isk::detail
