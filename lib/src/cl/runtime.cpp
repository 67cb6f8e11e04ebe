#include "isk/cl/runtime.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "isk/core/error.hpp"

namespace isk {
namespace {

struct DeviceEntry {
  cl::Platform platform;
  cl::Device device;
  ClDeviceInfo info;
};

ClDeviceInfo describeDevice(const cl::Platform& platform,
                            const cl::Device& device, int index) {
  ClDeviceInfo info;
  info.index = index;
  info.platform = platform.getInfo<CL_PLATFORM_NAME>();
  info.name = device.getInfo<CL_DEVICE_NAME>();
  info.version = device.getInfo<CL_DEVICE_VERSION>();
  const cl_device_type type = device.getInfo<CL_DEVICE_TYPE>();
  info.is_gpu = (type & CL_DEVICE_TYPE_GPU) != 0;
  info.is_cpu = (type & CL_DEVICE_TYPE_CPU) != 0;
  // Drivers pad names with spaces or NULs.
  while (!info.name.empty() &&
         (info.name.back() == '\0' || info.name.back() == ' ')) {
    info.name.pop_back();
  }
  while (!info.platform.empty() && info.platform.back() == '\0')
    info.platform.pop_back();
  return info;
}

// All devices; an absent ICD platform is "no device", not an error.
std::vector<DeviceEntry> enumerateDevices() {
  std::vector<DeviceEntry> entries;
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error&) {
    return entries;
  }
  for (const cl::Platform& platform : platforms) {
    std::vector<cl::Device> devices;
    try {
      platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;  // a platform without devices answers CL_DEVICE_NOT_FOUND
    }
    for (const cl::Device& device : devices) {
      const int index = static_cast<int>(entries.size());
      entries.push_back(
          {platform, device, describeDevice(platform, device, index)});
    }
  }
  return entries;
}

std::string listForMessage(const std::vector<DeviceEntry>& entries) {
  if (entries.empty()) {
    return "no OpenCL platform or device was found (is an ICD such as "
           "pocl-opencl-icd installed, and POCL_CACHE_DIR writable?)";
  }
  std::string text = "devices seen:";
  for (const DeviceEntry& e : entries) {
    text +=
        " [" + std::to_string(e.info.index) + "] " + e.info.describe() + ";";
  }
  return text;
}

// Per-device build options (CLBlast-style table): kept small on purpose.
std::string deviceBuildOptions(const ClDeviceInfo& info) {
  std::string options = "-cl-std=CL1.2";
  options += info.is_gpu ? " -DISK_DEVICE_GPU=1" : " -DISK_DEVICE_GPU=0";
  return options;
}

}  // namespace

void throwClError(const cl::Error& error, const std::string& what) {
  throw Error(
      ErrorCode::kOpenCl,
      what + ": " + error.what() + " failed with " + clStatusName(error.err()),
      error.err());
}

double eventMilliseconds(const cl::Event& event) {
  if (!event()) return 0.0;
  try {
    const cl_ulong start = event.getProfilingInfo<CL_PROFILING_COMMAND_START>();
    const cl_ulong end = event.getProfilingInfo<CL_PROFILING_COMMAND_END>();
    return end > start ? static_cast<double>(end - start) * 1e-6 : 0.0;
  } catch (const cl::Error&) {
    return 0.0;  // CL_PROFILING_INFO_NOT_AVAILABLE on queues without profiling
  }
}

std::vector<ClDeviceInfo> listClDevices() {
  std::vector<ClDeviceInfo> infos;
  for (const DeviceEntry& e : enumerateDevices()) infos.push_back(e.info);
  return infos;
}

std::shared_ptr<ClContext> ClContext::create(const std::string& selection_in) {
  std::string selection = selection_in;
  if (selection.empty() || selection == "auto") {
    const char* env = std::getenv("ISK_DEVICE");
    selection = (env && *env) ? env : "auto";
  }
  const std::vector<DeviceEntry> entries = enumerateDevices();
  const DeviceEntry* chosen = nullptr;
  if (selection == "auto") {
    for (const auto& e : entries) {
      if (!chosen && e.info.is_gpu) chosen = &e;
    }
    for (const auto& e : entries) {
      if (!chosen && e.info.is_cpu) chosen = &e;
    }
    if (!chosen && !entries.empty()) chosen = &entries.front();
  } else if (selection == "gpu" || selection == "cpu") {
    for (const auto& e : entries) {
      if (!chosen && (selection == "gpu" ? e.info.is_gpu : e.info.is_cpu))
        chosen = &e;
    }
  } else {
    std::string number = selection;
    if (number.rfind("opencl:", 0) == 0) number = number.substr(7);
    char* end = nullptr;
    const long index = std::strtol(number.c_str(), &end, 10);
    if (number.empty() || *end != '\0' || index < 0) {
      throw Error(ErrorCode::kInvalidArgument,
                  "device selection '" + selection +
                      "' is not one of auto, gpu, cpu, N or opencl:N");
    }
    if (index < static_cast<long>(entries.size())) chosen = &entries[index];
  }
  if (!chosen) {
    throw Error(ErrorCode::kNoDevice, "no OpenCL device matches '" + selection +
                                          "': " + listForMessage(entries));
  }
  std::shared_ptr<ClContext> result(new ClContext());
  try {
    result->device_ = chosen->device;
    result->context_ = cl::Context(chosen->device);
    result->queue_ = cl::CommandQueue(result->context_, chosen->device,
                                      CL_QUEUE_PROFILING_ENABLE);
  } catch (const cl::Error& e) {
    throwClError(e, "creating a context on " + chosen->info.describe());
  }
  result->info_ = chosen->info;
  result->profiling_ = true;
  result->initInfo();
  return result;
}

std::shared_ptr<ClContext> ClContext::wrap(cl_context context,
                                           cl_device_id device,
                                           cl_command_queue queue) {
  if (!context || !device || !queue) {
    throw Error(
        ErrorCode::kInvalidArgument,
        "ClContext::wrap: the context, device and queue must not be null");
  }
  std::shared_ptr<ClContext> result(new ClContext());
  try {
    result->context_ = cl::Context(context, /*retainObject=*/true);
    result->device_ = cl::Device(device, /*retainObject=*/true);
    result->queue_ = cl::CommandQueue(queue, /*retainObject=*/true);
    if (result->queue_.getInfo<CL_QUEUE_CONTEXT>()() != context ||
        result->queue_.getInfo<CL_QUEUE_DEVICE>()() != device) {
      throw Error(
          ErrorCode::kInvalidArgument,
          "ClContext::wrap: the queue does not belong to the given context "
          "and device");
    }
    const cl::Platform platform(result->device_.getInfo<CL_DEVICE_PLATFORM>(),
                                /*retainObject=*/true);
    result->info_ = describeDevice(platform, result->device_, -1);
    result->profiling_ = (result->queue_.getInfo<CL_QUEUE_PROPERTIES>() &
                          CL_QUEUE_PROFILING_ENABLE) != 0;
    result->initInfo();
  } catch (const cl::Error& e) {
    throwClError(e, "ClContext::wrap: querying the application's objects");
  }
  return result;
}

void ClContext::initInfo() {
  try {
    max_allocation_ =
        static_cast<size_t>(device_.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>());
  } catch (const cl::Error& e) {
    throwClError(e, "clGetDeviceInfo(CL_DEVICE_MAX_MEM_ALLOC_SIZE) on " +
                        info_.describe());
  }
}

cl::Buffer ClContext::createBuffer(cl_mem_flags flags, size_t bytes, void* host,
                                   const std::string& what) const {
  bytes = std::max<size_t>(bytes, 1);
  if (bytes > max_allocation_) {
    throw Error(ErrorCode::kOpenCl,
                what + ": a buffer of " + std::to_string(bytes) +
                    " bytes exceeds CL_DEVICE_MAX_MEM_ALLOC_SIZE (" +
                    std::to_string(max_allocation_) + " bytes) of " +
                    info_.describe(),
                CL_INVALID_BUFFER_SIZE);
  }
  try {
    return cl::Buffer(context_, flags, bytes, host);
  } catch (const cl::Error& e) {
    throw Error(ErrorCode::kOpenCl,
                what + ": clCreateBuffer of " + std::to_string(bytes) +
                    " bytes failed with " + clStatusName(e.err()) + " on " +
                    info_.describe(),
                e.err());
  }
}

std::string ClContext::buildOptions(const std::string& extra_options) const {
  std::string options = deviceBuildOptions(info_);
  if (!extra_options.empty()) options += " " + extra_options;
  return options;
}

int ClContext::cachedProgramCount() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(programs_.size());
}

namespace {

// A kernel file's source with its `#include "NAME.cl"` and `#include
// "NAME.h"` lines replaced by the embedded file (each file once): kernels
// share code and kernels/abi.h that way and still compile on their own with
// -I kernels.
void appendWithIncludes(const std::string& kernel_file,
                        std::vector<std::string>& seen, std::string& out) {
  if (std::find(seen.begin(), seen.end(), kernel_file) != seen.end()) return;
  seen.push_back(kernel_file);
  const std::string source = embeddedKernelSource(kernel_file);
  size_t line_start = 0;
  while (line_start < source.size()) {
    size_t line_end = source.find('\n', line_start);
    if (line_end == std::string::npos) line_end = source.size();
    const std::string line = source.substr(line_start, line_end - line_start);
    const std::string prefix = "#include \"";
    if (line.rfind(prefix, 0) == 0 && line.size() > prefix.size() + 4 &&
        line.compare(line.size() - 4, 4, ".cl\"") == 0) {
      appendWithIncludes(
          line.substr(prefix.size(), line.size() - prefix.size() - 4), seen,
          out);
      out += "\n";
    } else if (line.rfind(prefix, 0) == 0 && line.size() > prefix.size() + 3 &&
               line.compare(line.size() - 3, 3, ".h\"") == 0) {
      appendWithIncludes(
          line.substr(prefix.size(), line.size() - prefix.size() - 1), seen,
          out);
      out += "\n";
    } else {
      out += line;
      out += "\n";
    }
    line_start = line_end + 1;
  }
}

std::string withEmbeddedIncludes(const std::string& kernel_file) {
  std::vector<std::string> seen;
  std::string out;
  appendWithIncludes(kernel_file, seen, out);
  return out;
}

}  // namespace

cl::Program ClContext::program(const std::string& kernel_file,
                               const std::string& extra_options) {
  const std::string options = buildOptions(extra_options);
  const std::string key = kernel_file + "\n" + options;
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  const std::string source = withEmbeddedIncludes(kernel_file);
  cl::Program program;
  try {
    program = cl::Program(context_, source);
  } catch (const cl::Error& e) {
    throwClError(e, "kernels/" + kernel_file + ".cl");
  }
  try {
    program.build(std::vector<cl::Device>{device_}, options.c_str());
  } catch (const cl::Error& e) {
    std::string log;
    try {
      log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device_);
    } catch (const cl::Error&) {
      log = "(no build log)";
    }
    throw Error(ErrorCode::kOpenCl,
                "kernels/" + kernel_file + ".cl: clBuildProgram failed with " +
                    clStatusName(e.err()) + " on " + info_.describe() +
                    " with options '" + options + "':\n" + log,
                e.err());
  }
  programs_.emplace(key, program);
  return program;
}

}  // namespace isk
