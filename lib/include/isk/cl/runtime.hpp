// OpenCL runtime: device selection, context and queue, cache of built programs.
//
// Device selection (ClContext::create):
//   ""/"auto"   the ISK_DEVICE environment variable if set, else the first GPU,
//               else the first CPU device (such as PoCL), else any device;
//   "gpu"/"cpu" the first device of that type;
//   "N" or "opencl:N"  device N in listClDevices() order (platforms in ICD
//               order, devices in platform order).
// An application can hand in its own context, device and queue instead
// (ClContext::wrap); the library then retains them and never creates others.
//
// Built programs are cached per ClContext (one context + device) and per
// build options. Build options come from a small per-device table: every
// build gets -cl-std=CL1.2 and ISK_DEVICE_GPU=0/1.
//
// Every OpenCL failure is thrown as isk::Error(kOpenCl) whose message names
// the failing OpenCL call and its status name; build failures carry the log.
#pragma once

#include <CL/opencl.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace isk {

// What listClDevices() and ClContext::info() say about a device.
struct ClDeviceInfo {
  int index = -1;  // position in listClDevices()
  std::string platform;
  std::string name;
  std::string version;  // CL_DEVICE_VERSION
  bool is_gpu = false;
  bool is_cpu = false;
  // "platform / device".
  std::string describe() const { return platform + " / " + name; }
};

// Every device of every platform, in selection order. An empty list when no
// platform is installed (never throws for that).
std::vector<ClDeviceInfo> listClDevices();

// One OpenCL context, device and in-order queue, and the programs built on
// them. program() is thread-safe; share the context (std::shared_ptr)
// between the skinners of several characters.
class ClContext {
 public:
  // Picks a device as described above and creates a context and an in-order
  // queue with profiling enabled. Throws isk::Error(kNoDevice) when nothing
  // matches (the message lists the devices seen) or kInvalidArgument for a
  // malformed selection.
  static std::shared_ptr<ClContext> create(const std::string& selection = "");

  // Uses the application's objects (retained, not copied). The queue must
  // belong to the context and the device. Throws isk::Error(kInvalidArgument)
  // when they do not match, kOpenCl when a query fails.
  static std::shared_ptr<ClContext> wrap(cl_context context,
                                         cl_device_id device,
                                         cl_command_queue queue);

  const cl::Context& context() const { return context_; }
  const cl::Device& device() const { return device_; }
  const cl::CommandQueue& queue() const { return queue_; }
  const ClDeviceInfo& info() const { return info_; }
  // True when the queue records profiling info (events give kernel times).
  bool profilingEnabled() const { return profiling_; }
  // CL_DEVICE_MAX_MEM_ALLOC_SIZE: the largest buffer the device takes.
  size_t maxAllocationBytes() const { return max_allocation_; }

  // A buffer of `bytes` (0 is raised to 1: OpenCL has no empty buffers) in
  // this context, `host` copied when flags ask for it. Throws
  // isk::Error(kOpenCl, CL_INVALID_BUFFER_SIZE) naming `what`, the size and
  // the device's limit when `bytes` exceeds maxAllocationBytes(), and
  // kOpenCl naming clCreateBuffer, `what` and the size when the call fails
  // (CL_MEM_OBJECT_ALLOCATION_FAILURE, CL_OUT_OF_HOST_MEMORY...).
  cl::Buffer createBuffer(cl_mem_flags flags, size_t bytes, void* host,
                          const std::string& what) const;

  // The built program of embedded kernel file `kernel_file` (name without
  // .cl), built with buildOptions(extra_options); cached. Throws
  // isk::Error(kInvalidArgument) for an unknown file, kOpenCl with the build
  // log when the build fails.
  cl::Program program(const std::string& kernel_file,
                      const std::string& extra_options = "");
  // The options every build gets (see above), then `extra_options`.
  std::string buildOptions(const std::string& extra_options = "") const;
  // Programs built so far by this context.
  int cachedProgramCount() const;

 private:
  ClContext() = default;
  void initInfo();

  cl::Context context_;
  cl::Device device_;
  cl::CommandQueue queue_;
  ClDeviceInfo info_;
  bool profiling_ = false;
  size_t max_allocation_ = 0;
  mutable std::mutex mutex_;
  std::map<std::string, cl::Program> programs_;
};

// Names of the embedded kernel files (without .cl).
std::vector<std::string> embeddedKernelNames();
// Source of an embedded kernel file; throws isk::Error(kInvalidArgument).
std::string embeddedKernelSource(const std::string& kernel_file);

// Converts an OpenCL C++ binding exception into isk::Error naming the call.
[[noreturn]] void throwClError(const cl::Error& error, const std::string& what);

// Milliseconds between an event's start and end (0 when profiling is off).
double eventMilliseconds(const cl::Event& event);

}  // namespace isk
