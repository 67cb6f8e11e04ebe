// OpenCL faults: what each one yields (an isk::Error with a code and a
// message naming the call or the cause), and the CPU reference without any
// OpenCL platform.
#include <CL/cl.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "reference_fingerprint.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The probe in a process whose ICD loader finds no vendor file: ocl-icd
// reads OCL_ICD_VENDORS instead of /etc/OpenCL/vendors, and an empty folder
// leaves clGetPlatformIDs with CL_PLATFORM_NOT_FOUND_KHR.
test::RunOutput runWithoutPlatform() {
  test::ScopedTempDir empty;
  return test::runProgram(
      ISK_NO_DEVICE_PROBE_EXE, {},
      "OCL_ICD_VENDORS=" + test::shellQuote(empty.path().string()) + " ");
}

TEST(ClFaults, NoPlatformGivesNoDeviceWithAClearMessage) {
  const test::RunOutput run = runWithoutPlatform();
  const std::string what = test::describeRun("isk_no_device_probe", {}, run);
  ASSERT_EQ(run.exit_code, 0) << what;
  EXPECT_TRUE(contains(run.output, "devices 0\n")) << what;
  EXPECT_TRUE(contains(run.output,
                       "create no_device: no OpenCL device matches 'auto': "
                       "no OpenCL platform or device was found"))
      << what;
  EXPECT_TRUE(contains(run.output, "pocl-opencl-icd")) << what;
  // The same probe with the system's ICDs finds the device the tests use.
  const test::RunOutput normal = test::runProgram(ISK_NO_DEVICE_PROBE_EXE, {});
  EXPECT_TRUE(contains(normal.output,
                       "create ok " + test::sharedContext()->info().describe()))
      << test::describeRun("isk_no_device_probe", {}, normal);
}

TEST(ClFaults, CpuReferenceRunsWithoutAnyPlatform) {
  const test::RunOutput run = runWithoutPlatform();
  const std::string what = test::describeRun("isk_no_device_probe", {}, run);
  ASSERT_EQ(run.exit_code, 0) << what;
  // LBS, DQS and implicit skinning (fields, tracking, normals) give the
  // same bits there as in this process, which has a device.
  const std::string expected = test::referenceFingerprint();
  EXPECT_TRUE(contains(expected, " finite 1")) << expected;
  EXPECT_TRUE(contains(run.output, expected + "\n"))
      << "expected '" << expected << "'\n"
      << what;
}

TEST(ClFaults, NoMatchingDeviceNamesTheSelectionAndTheDevicesSeen) {
  const auto devices = listClDevices();
  ASSERT_FALSE(devices.empty());
  const std::string past_end = "opencl:" + std::to_string(devices.size());
  {
    test::ScopedEnv env("ISK_DEVICE", past_end.c_str());
    try {
      ClContext::create("");
      FAIL() << "ISK_DEVICE=" << past_end << " was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kNoDevice);
      const std::string message = e.what();
      EXPECT_TRUE(contains(message, "'" + past_end + "'")) << message;
      EXPECT_TRUE(
          contains(message, "devices seen: [0] " + devices[0].describe()))
          << message;
    }
  }
  {
    test::ScopedEnv env("ISK_DEVICE", "fastest-gpu");
    try {
      ClContext::create("");
      FAIL() << "ISK_DEVICE=fastest-gpu was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_TRUE(contains(e.what(), "'fastest-gpu' is not one of"))
          << e.what();
    }
  }
  // A type no device has (PoCL in CI: no GPU).
  bool any_gpu = false, any_cpu = false;
  for (const auto& d : devices) any_gpu |= d.is_gpu, any_cpu |= d.is_cpu;
  for (const char* type : {"gpu", "cpu"}) {
    const bool present = std::string(type) == "gpu" ? any_gpu : any_cpu;
    if (present) {
      EXPECT_NO_THROW(ClContext::create(type)) << type;
      continue;
    }
    try {
      ClContext::create(type);
      FAIL() << type << " was accepted without such a device";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kNoDevice);
      EXPECT_TRUE(contains(e.what(), std::string("matches '") + type + "'"))
          << e.what();
    }
  }
}

TEST(ClFaults, ProgramThatFailsToBuildCarriesTheBuildLog) {
  auto context = ClContext::create("");
  try {
    // The source no longer compiles: a function's name becomes a number.
    context->program("skinning", "-Dquat_rotate=42");
    FAIL() << "a program that cannot compile was built";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOpenCl);
    EXPECT_EQ(e.clStatus(), CL_BUILD_PROGRAM_FAILURE);
    const std::string message = e.what();
    EXPECT_TRUE(contains(message,
                         "kernels/skinning.cl: clBuildProgram "
                         "failed with CL_BUILD_PROGRAM_FAILURE"))
        << message;
    EXPECT_TRUE(contains(message, "-Dquat_rotate=42")) << message;
    // The compiler's log follows (PoCL: "expected identifier or '('" at
    // the function the macro renamed).
    const size_t log = message.find("':\n");
    ASSERT_NE(log, std::string::npos) << message;
    EXPECT_GT(message.size() - log, 20u) << message;
    EXPECT_TRUE(contains(message.substr(log), "error")) << message;
  }
  // The failure is not cached: a good build of the same file still works.
  EXPECT_NO_THROW(context->program("skinning"));
  EXPECT_EQ(context->cachedProgramCount(), 1);
}

TEST(ClFaults, BufferBeyondTheDeviceLimitIsATypedErrorWithItsSize) {
  auto context = test::sharedContext();
  const size_t limit = context->maxAllocationBytes();
  ASSERT_GT(limit, 0u);
  try {
    context->createBuffer(CL_MEM_READ_WRITE, limit + 1, nullptr, "a test");
    FAIL() << "a buffer of " << limit + 1 << " bytes was created";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOpenCl);
    EXPECT_EQ(e.clStatus(), CL_INVALID_BUFFER_SIZE);
    EXPECT_TRUE(contains(e.what(), "a test: a buffer of " +
                                       std::to_string(limit + 1) +
                                       " bytes exceeds "
                                       "CL_DEVICE_MAX_MEM_ALLOC_SIZE (" +
                                       std::to_string(limit) + " bytes)"))
        << e.what();
  }
  EXPECT_NO_THROW(
      context->createBuffer(CL_MEM_READ_WRITE, 1024, nullptr, "a test"));
}

TEST(ClFaults, PerFieldResultsBeyondTheDeviceLimitAreATypedError) {
  // 64 tiny fields: per-field results take 64 float4 per point, so a few
  // million points ask for more than one buffer may hold while the points
  // themselves stay small.
  auto context = test::sharedContext();
  const int fields = 64;
  FieldGridSet grids;
  grids.resolution = 2;
  for (int j = 0; j < fields; ++j) {
    FieldGrid grid;
    grid.joint = j;
    grid.resolution = 2;
    grid.box_min = Eigen::Vector3f::Constant(-1.f);
    grid.box_max = Eigen::Vector3f::Constant(1.f);
    grid.nodes.assign(4 * 8, 0.f);
    grids.grids.push_back(grid);
    grids.field_of_joint.push_back(j);
  }
  ClFieldEvaluation evaluation(context, grids, fields, FieldStorage::kBuffer);
  const size_t limit = context->maxAllocationBytes();
  const size_t per_point = 4 * sizeof(float) * fields;
  const size_t count = limit / per_point + 1;
  ASSERT_LT(count, size_t{1} << 31);
  ASSERT_LE(3 * sizeof(float) * count, limit);
  cl::Buffer points(context->context(), CL_MEM_READ_ONLY,
                    3 * sizeof(float) * count);
  const TransformList pose(fields, Eigen::Affine3f::Identity());
  try {
    evaluation.evaluate(pose, points, static_cast<int>(count), true);
    FAIL() << "per-field results of " << count * per_point
           << " bytes were allocated";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOpenCl);
    EXPECT_EQ(e.clStatus(), CL_INVALID_BUFFER_SIZE);
    const std::string message = e.what();
    EXPECT_TRUE(contains(message, "per-field values of " +
                                      std::to_string(count) +
                                      " points x 64 "
                                      "fields"))
        << message;
    EXPECT_TRUE(contains(message, std::to_string(count * per_point) +
                                      " bytes exceeds "
                                      "CL_DEVICE_MAX_MEM_ALLOC_SIZE"))
        << message;
  }
  // The composed values alone fit: the same call without per-field
  // results runs.
  Matrix3Xf few(3, 3);
  few.setZero();
  Matrix4Xf composed;
  EXPECT_NO_THROW(evaluation.evaluate(pose, few, composed));
  EXPECT_EQ(composed.rows(), 3);
}

TEST(ClFaults, ApplicationContextThatIsNullOrForeignIsATypedError) {
  auto owner = ClContext::create("");
  const cl_context c = owner->context()();
  const cl_device_id d = owner->device()();
  const cl_command_queue q = owner->queue()();
  struct Case {
    cl_context context;
    cl_device_id device;
    cl_command_queue queue;
  };
  for (const Case& bad :
       {Case{nullptr, d, q}, Case{c, nullptr, q}, Case{c, d, nullptr},
        Case{nullptr, nullptr, nullptr}}) {
    try {
      ClContext::wrap(bad.context, bad.device, bad.queue);
      FAIL() << "a null handle was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_TRUE(contains(e.what(),
                           "ClContext::wrap: the context, device "
                           "and queue must not be null"))
          << e.what();
    }
  }
  // A queue of another context.
  auto other = ClContext::create("");
  try {
    ClContext::wrap(c, d, other->queue()());
    FAIL() << "a queue of another context was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_TRUE(contains(e.what(), "does not belong")) << e.what();
  }
}

TEST(ClFaults, ApplicationReleasingItsHandlesAfterWrapLeavesThemUsable) {
  // The application creates its own objects, hands them over and drops its
  // references: the library retained them, so they stay valid.
  const ClDeviceInfo info = test::sharedContext()->info();
  cl_device_id device = test::sharedContext()->device()();
  cl_int status = CL_SUCCESS;
  cl_context context =
      clCreateContext(nullptr, 1, &device, nullptr, nullptr, &status);
  ASSERT_EQ(status, CL_SUCCESS);
  cl_command_queue queue =
      clCreateCommandQueue(context, device, 0, &status);  // no profiling
  ASSERT_EQ(status, CL_SUCCESS);
  auto wrapped = ClContext::wrap(context, device, queue);
  EXPECT_EQ(clReleaseCommandQueue(queue), CL_SUCCESS);
  EXPECT_EQ(clReleaseContext(context), CL_SUCCESS);
  EXPECT_FALSE(wrapped->profilingEnabled());
  EXPECT_EQ(wrapped->maxAllocationBytes(),
            test::sharedContext()->maxAllocationBytes());
  Rig rig = makeCylinderRig();
  ClSkinning skinning(wrapped, rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  skinning.run(SkinningMethod::kDualQuaternion, bindPoseSkinning(rig.skeleton));
  Matrix3Xf positions;
  skinning.readPositions(positions);
  EXPECT_LE(test::largestRowDistance(positions, rig.mesh.positions).distance,
            1e-5f);
  EXPECT_EQ(wrapped->info().name, info.name);
}

}  // namespace
}  // namespace isk
