// What every kernel file starts with: the host-kernel ABI and the kernels'
// shared settings. OpenCL C only (the host includes abi.h itself).
#ifndef ISK_KERNELS_COMMON_H
#define ISK_KERNELS_COMMON_H

// The CPU reference computes without fused multiply-adds; so do the
// kernels, so that on a CPU device both agree to the last bits.
#pragma OPENCL FP_CONTRACT OFF

#include "abi.h"

// The per-sample helpers are inlined into their callers: on a CPU device
// (PoCL) a call per field sample keeps the grid loads of consecutive fields
// from overlapping.
#define ISK_INLINE inline __attribute__((always_inline))

#endif  // ISK_KERNELS_COMMON_H
