#include "skin_targets.hpp"

#include <filesystem>
#include <system_error>

#include "isk/core/error.hpp"

namespace isk::samples::skin {
namespace fs = std::filesystem;

namespace {

bool isFrameFileName(const std::string& name) {
  return name.rfind("frame_", 0) == 0 &&
         (name.size() > 4 && (name.compare(name.size() - 4, 4, ".obj") == 0 ||
                              name.compare(name.size() - 4, 4, ".ply") == 0));
}

}  // namespace

void checkGltfTarget(const Options& options) {
  if (!isBuiltinInput(options.input) && samePath(options.gltf, options.input)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--gltf " + options.gltf + " is the input file");
  }
  std::error_code ec;
  if (fs::is_directory(options.gltf, ec)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--gltf " + options.gltf + " is a folder");
  }
}

void checkReportTarget(const Options& options) {
  if (!isBuiltinInput(options.input) &&
      samePath(options.report, options.input)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--report " + options.report + " is the input file");
  }
  const fs::path report(options.report);
  std::error_code ec;
  if (fs::is_directory(report, ec)) {
    throw Error(ErrorCode::kIo, "--report " + options.report + ": is a folder");
  }
  if (fs::exists(report, ec) && !options.overwrite) {
    throw Error(ErrorCode::kIo,
                "--report " + options.report +
                    ": the file exists; pass --overwrite to replace it "
                    "or choose another name");
  }
  if (options.out_dir.empty()) return;
  const fs::path parent =
      report.has_parent_path() ? report.parent_path() : fs::path(".");
  if (isFrameFileName(report.filename().string()) &&
      fs::weakly_canonical(parent, ec) ==
          fs::weakly_canonical(fs::path(options.out_dir), ec)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--report " + options.report +
                    ": a frame file of --out would replace it");
  }
}

void checkSaveParamsTarget(const Options& options) {
  if (!isBuiltinInput(options.input) &&
      samePath(options.save_params, options.input)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--save-params " + options.save_params + " is the input file");
  }
}

void createParentFolder(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
}

}  // namespace isk::samples::skin
