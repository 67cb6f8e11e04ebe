#include "data_folder.hpp"

#include <cstdlib>
#include <filesystem>

namespace isk::samples {

std::string dataFolder() {
  if (const char* env = std::getenv("ISK_DATA_DIR"); env && *env) return env;
  return ISK_DEFAULT_DATA_DIR;
}

std::string dataFile(const std::string& file) {
  return dataFolder() + "/" + file;
}

bool dataFolderPresent() {
  std::error_code ec;
  return std::filesystem::is_directory(dataFolder(), ec);
}

}  // namespace isk::samples
