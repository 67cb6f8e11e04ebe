// OpenCL runtime: device selection, application-supplied objects, program
// cache, embedded kernels, and errors that name the failing call.
#include "isk/cl/runtime.hpp"

#include <gtest/gtest.h>

#include <cstdlib>

#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

TEST(Runtime, ListsDevicesAndCreatesTheDefaultContext) {
  const auto devices = listClDevices();
  ASSERT_FALSE(devices.empty())
      << "no OpenCL device: install an ICD (pocl-opencl-icd)";
  for (size_t i = 0; i < devices.size(); ++i) {
    EXPECT_EQ(devices[i].index, static_cast<int>(i));
    EXPECT_FALSE(devices[i].name.empty());
  }
  auto context = ClContext::create("");
  EXPECT_TRUE(context->profilingEnabled());
  // auto: a GPU when there is one, else a CPU device.
  bool any_gpu = false;
  for (const auto& d : devices) any_gpu |= d.is_gpu;
  if (std::getenv("ISK_DEVICE") == nullptr) {
    EXPECT_EQ(context->info().is_gpu, any_gpu) << context->info().describe();
  }
}

TEST(Runtime, SelectsByIndexAndByType) {
  const auto devices = listClDevices();
  ASSERT_FALSE(devices.empty());
  auto by_index = ClContext::create("opencl:0");
  EXPECT_EQ(by_index->info().name, devices[0].name);
  auto plain_index = ClContext::create("0");
  EXPECT_EQ(plain_index->info().name, devices[0].name);
  const std::string type = devices[0].is_gpu ? "gpu" : "cpu";
  if (devices[0].is_gpu || devices[0].is_cpu) {
    EXPECT_NO_THROW(ClContext::create(type));
  }
}

TEST(Runtime, BadSelectionsGiveTypedErrors) {
  try {
    ClContext::create("opencl:999");
    FAIL() << "device 999 was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNoDevice);
    EXPECT_NE(std::string(e.what()).find("devices seen"), std::string::npos)
        << e.what();
  }
  try {
    ClContext::create("fastest");
    FAIL() << "a malformed selection was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("fastest"), std::string::npos);
  }
}

TEST(Runtime, EnvironmentVariableOverridesAuto) {
  {
    test::ScopedEnv env("ISK_DEVICE", "opencl:999");
    EXPECT_THROW(ClContext::create(""), Error);
    // An explicit argument wins over the environment.
    EXPECT_NO_THROW(ClContext::create("opencl:0"));
  }
  test::ScopedEnv env("ISK_DEVICE", "opencl:0");
  EXPECT_EQ(ClContext::create("")->info().name, listClDevices()[0].name);
}

TEST(Runtime, ProgramsAreCachedPerOptions) {
  auto context = ClContext::create("");
  EXPECT_EQ(context->cachedProgramCount(), 0);
  cl::Program first = context->program("skinning");
  cl::Program second = context->program("skinning");
  EXPECT_EQ(first(), second());
  EXPECT_EQ(context->cachedProgramCount(), 1);
  context->program("skinning", "-DISK_UNUSED_DEFINE=1");
  EXPECT_EQ(context->cachedProgramCount(), 2);
  EXPECT_NE(context->buildOptions().find("-cl-std=CL1.2"), std::string::npos);
}

TEST(Runtime, EveryEmbeddedKernelFileBuildsOnItsOwn) {
  auto context = test::sharedContext();
  const auto names = embeddedKernelNames();
  EXPECT_GE(names.size(), 2u);
  for (const std::string& name : names) {
    EXPECT_FALSE(embeddedKernelSource(name).empty());
    EXPECT_NO_THROW(context->program(name)) << "kernels/" << name << ".cl";
  }
  EXPECT_THROW(embeddedKernelSource("no_such_kernel"), Error);
}

TEST(Runtime, BuildFailureNamesTheCallAndTheFile) {
  auto context = ClContext::create("");
  try {
    context->program("skinning", "-DISK_BROKEN -cl-no-such-option");
    FAIL() << "an invalid build option was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOpenCl);
    EXPECT_NE(e.clStatus(), 0);
    const std::string message = e.what();
    EXPECT_NE(message.find("clBuildProgram"), std::string::npos) << message;
    EXPECT_NE(message.find("kernels/skinning.cl"), std::string::npos)
        << message;
  }
}

TEST(Runtime, WrapsTheApplicationsContextAndQueue) {
  auto owner = ClContext::create("");
  auto wrapped =
      ClContext::wrap(owner->context()(), owner->device()(), owner->queue()());
  EXPECT_EQ(wrapped->context()(), owner->context()());
  EXPECT_EQ(wrapped->info().name, owner->info().name);
  EXPECT_TRUE(wrapped->profilingEnabled());
  // The wrapped context runs the kernels like an owned one.
  Rig rig = makeCylinderRig();
  ClSkinning skinning(wrapped, rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  skinning.run(SkinningMethod::kDualQuaternion, bindPoseSkinning(rig.skeleton));
  Matrix3Xf positions;
  skinning.readPositions(positions);
  EXPECT_LE(test::largestRowDistance(positions, rig.mesh.positions).distance,
            1e-5f);

  // A queue of another context is refused with a reason.
  auto other = ClContext::create("");
  try {
    ClContext::wrap(owner->context()(), owner->device()(), other->queue()());
    FAIL() << "a foreign queue was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("does not belong"), std::string::npos);
  }
  EXPECT_THROW(ClContext::wrap(nullptr, nullptr, nullptr), Error);
}

TEST(Runtime, StatusNamesAreReadable) {
  EXPECT_EQ(clStatusName(CL_OUT_OF_RESOURCES), "CL_OUT_OF_RESOURCES");
  EXPECT_EQ(clStatusName(CL_BUILD_PROGRAM_FAILURE), "CL_BUILD_PROGRAM_FAILURE");
  EXPECT_EQ(clStatusName(-12345), "CL_ERROR(-12345)");
  EXPECT_STREQ(errorCodeName(ErrorCode::kOpenCl), "opencl");
}

TEST(Runtime, StageTimesComeFromProfilingEvents) {
  Rig rig = makeBuiltinRig("arm");
  ClSkinning skinning(test::sharedContext(), rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  skinning.run(SkinningMethod::kLinearBlend, bindPoseSkinning(rig.skeleton),
               true);
  Matrix3Xf out;
  skinning.readPositions(out);
  const SkinningStageTimes& t = skinning.lastTimes();
  EXPECT_GT(t.skinning_ms, 0.0);
  EXPECT_GT(t.normals_ms, 0.0);
  EXPECT_GE(t.readback_ms, 0.0);
}

}  // namespace
}  // namespace isk
