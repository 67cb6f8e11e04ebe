// isk_no_device_probe: what the library does in a process that sees no
// OpenCL platform (the fault tests run it with OCL_ICD_VENDORS pointing at
// an empty folder). Prints, one per line:
//   devices N
//   create <error code name>: <message>     (or "create ok <device>")
//   reference <hash> finite <0|1>           (tests/reference_fingerprint.hpp)
// and exits 0 when nothing escaped as an unexpected exception.
#include <cstdio>
#include <exception>

#include "isk/cl/runtime.hpp"
#include "isk/core/error.hpp"
#include "reference_fingerprint.hpp"

int main() {
  try {
    std::printf("devices %zu\n", isk::listClDevices().size());
    try {
      auto context = isk::ClContext::create("");
      std::printf("create ok %s\n", context->info().describe().c_str());
    } catch (const isk::Error& e) {
      std::printf("create %s: %s\n", isk::errorCodeName(e.code()), e.what());
    }
    std::printf("%s\n", isk::test::referenceFingerprint().c_str());
  } catch (const std::exception& e) {
    std::printf("unexpected exception: %s\n", e.what());
    return 1;
  }
  return 0;
}
