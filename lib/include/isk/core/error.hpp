// Errors thrown by the isk library.
//
// Every failure inside the library surfaces as one exception type, isk::Error,
// carrying a code and a message that names what failed and where: the file,
// mesh, joint or vertex for bad input, the OpenCL call and its status for
// device failures.
#pragma once

#include <stdexcept>
#include <string>

namespace isk {

// What kind of failure an isk::Error is.
enum class ErrorCode {
  kInvalidArgument,  // the caller passed something malformed (sizes, indices)
  kIo,               // a file could not be read or written
  kMalformedAsset,   // an asset was read but its content is unusable
  kNoDevice,         // no OpenCL platform/device matches the request
  kOpenCl,           // an OpenCL call failed (clStatus() holds the code)
  kInternal,         // a broken invariant inside the library
  kLimitExceeded,    // a time or memory limit the caller set was reached
};

// Short stable name of a code ("invalid_argument", "opencl", ...).
const char* errorCodeName(ErrorCode code);

// Name of an OpenCL status code ("CL_OUT_OF_RESOURCES"), or "CL_ERROR(<n>)".
std::string clStatusName(int status);

// The one exception type of the library; what() is the message.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message, int cl_status = 0)
      : std::runtime_error(message), code_(code), cl_status_(cl_status) {}

  ErrorCode code() const { return code_; }
  // The OpenCL status when code() == kOpenCl, else 0.
  int clStatus() const { return cl_status_; }

 private:
  ErrorCode code_;
  int cl_status_;
};

}  // namespace isk
