// Where isk-skin writes, and what it refuses to write over: the input, a
// folder, an existing report without --overwrite, a report a frame file
// would replace. Each check runs before the work it guards, so that a
// refused run writes nothing; each throws isk::Error naming the option.
#pragma once

#include <string>

#include "skin_options.hpp"

namespace isk::samples::skin {

// --gltf FILE.glb: refuses the input file and a folder.
void checkGltfTarget(const Options& options);

// --report FILE: refuses the input file, a folder, an existing file (unless
// --overwrite) and a frame file's name in --out.
void checkReportTarget(const Options& options);

// --save-params FILE: refuses the input file.
void checkSaveParamsTarget(const Options& options);

// Creates the folder that will hold `path` when it has one.
void createParentFolder(const std::string& path);

}  // namespace isk::samples::skin
