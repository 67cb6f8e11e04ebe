// The one data-folder setting of tests, benchmarks and samples.
#pragma once

#include <string>

namespace isk::samples {

// The folder of the shared test assets: $ISK_DATA_DIR when set, else the
// default configured at build time (../shared/data beside the source tree).
std::string dataFolder();

// dataFolder() + "/" + file.
std::string dataFile(const std::string& file);

// True when the folder exists.
bool dataFolderPresent();

}  // namespace isk::samples
