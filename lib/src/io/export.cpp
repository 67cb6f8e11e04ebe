#include "isk/io/export.hpp"

#include <charconv>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <utility>

#include "core/cache_file.hpp"
#include "isk/core/error.hpp"

namespace isk {
namespace {

// Buffered output to a file written atomically: the writers stay linear,
// the file gets 1 MiB writes, and its first failure is reported once at the
// end (AtomicFileWriter keeps it).
class FileSink {
 public:
  explicit FileSink(detail::AtomicFileWriter& file) : file_(file) {
    buffer_.reserve(kChunk);
  }

  void append(const char* data, size_t size) {
    buffer_.append(data, size);
    if (buffer_.size() >= kChunk) flush();
  }
  void append(const std::string& s) { append(s.data(), s.size()); }
  void append(char c) { append(&c, 1); }

  void flush() {
    if (!buffer_.empty()) file_.write(buffer_.data(), buffer_.size());
    buffer_.clear();
  }

 private:
  static constexpr size_t kChunk = 1 << 20;
  detail::AtomicFileWriter& file_;
  std::string buffer_;
};

// Shortest text that reads back to the same float, independent of the
// locale (printf's %g would write a decimal comma in some locales).
void appendFloat(FileSink& sink, float value) {
  char text[32];
  auto result = std::to_chars(text, text + sizeof(text), value);
  sink.append(text, static_cast<size_t>(result.ptr - text));
}

void appendInt(FileSink& sink, int64_t value) {
  char text[24];
  auto result = std::to_chars(text, text + sizeof(text), value);
  sink.append(text, static_cast<size_t>(result.ptr - text));
}

void writeObj(FileSink& sink, const Matrix3Xf& positions,
              const Matrix3Xf* normals, const TriangleMatrix& triangles) {
  sink.append("# written by isk\n");
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    sink.append('v');
    for (int c = 0; c < 3; ++c) {
      sink.append(' ');
      appendFloat(sink, positions(v, c));
    }
    sink.append('\n');
  }
  if (normals) {
    for (Eigen::Index v = 0; v < normals->rows(); ++v) {
      sink.append("vn");
      for (int c = 0; c < 3; ++c) {
        sink.append(' ');
        appendFloat(sink, (*normals)(v, c));
      }
      sink.append('\n');
    }
  }
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    sink.append('f');
    for (int c = 0; c < 3; ++c) {
      const int64_t index = static_cast<int64_t>(triangles(f, c)) + 1;
      sink.append(' ');
      appendInt(sink, index);
      if (normals) {
        sink.append("//");
        appendInt(sink, index);
      }
    }
    sink.append('\n');
  }
}

bool hostIsLittleEndian() {
  const uint32_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Appends the 4 bytes of a float or int32 in little-endian order.
template <typename T>
void appendLittleEndian(FileSink& sink, T value, bool swap) {
  static_assert(sizeof(T) == 4, "PLY fields are 4 bytes");
  char bytes[4];
  std::memcpy(bytes, &value, 4);
  if (swap) {
    std::swap(bytes[0], bytes[3]);
    std::swap(bytes[1], bytes[2]);
  }
  sink.append(bytes, 4);
}

void writePly(FileSink& sink, const Matrix3Xf& positions,
              const Matrix3Xf* normals, const TriangleMatrix& triangles) {
  std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment written by isk\n";
  header += "element vertex " + std::to_string(positions.rows()) + "\n";
  header += "property float x\nproperty float y\nproperty float z\n";
  if (normals) {
    header += "property float nx\nproperty float ny\nproperty float nz\n";
  }
  header += "element face " + std::to_string(triangles.rows()) + "\n";
  header += "property list uchar int vertex_indices\nend_header\n";
  sink.append(header);

  const bool swap = !hostIsLittleEndian();
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    for (int c = 0; c < 3; ++c) {
      appendLittleEndian(sink, positions(v, c), swap);
    }
    if (normals) {
      for (int c = 0; c < 3; ++c) {
        appendLittleEndian(sink, (*normals)(v, c), swap);
      }
    }
  }
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    sink.append(static_cast<char>(3));
    for (int c = 0; c < 3; ++c) {
      appendLittleEndian(sink, static_cast<int32_t>(triangles(f, c)), swap);
    }
  }
}

void checkInputs(const std::string& path, const Matrix3Xf& positions,
                 const Matrix3Xf* normals, const TriangleMatrix& triangles) {
  if (normals && normals->rows() != positions.rows()) {
    throw Error(ErrorCode::kInvalidArgument,
                "writeMesh(" + path + "): " + std::to_string(normals->rows()) +
                    " normals for " + std::to_string(positions.rows()) +
                    " vertices");
  }
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const int32_t index = triangles(f, c);
      if (index < 0 || index >= positions.rows()) {
        throw Error(ErrorCode::kInvalidArgument,
                    "writeMesh(" + path + "): triangle " + std::to_string(f) +
                        " refers to vertex " + std::to_string(index) + " of " +
                        std::to_string(positions.rows()));
      }
    }
  }
}

// Runs `write` into a temporary file beside `path` and renames it to `path`
// when complete, so a failure never leaves a partial file under `path`.
// The folder must exist: a mistyped folder is an error, not a new folder.
void writeAtomically(const std::string& path,
                     const std::function<void(FileSink&)>& write) {
  detail::AtomicFileWriter file(path, detail::ParentFolder::kMustExist);
  if (file.failed()) throw Error(ErrorCode::kIo, path + ": " + file.error());
  FileSink sink(file);
  write(sink);
  sink.flush();
  if (!file.commit()) throw Error(ErrorCode::kIo, path + ": " + file.error());
}

}  // namespace

void writeMesh(const std::string& path, MeshFormat format,
               const Matrix3Xf& positions, const Matrix3Xf* normals,
               const TriangleMatrix& triangles) {
  checkInputs(path, positions, normals, triangles);
  writeAtomically(path, [&](FileSink& sink) {
    if (format == MeshFormat::kObj) {
      writeObj(sink, positions, normals, triangles);
    } else {
      writePly(sink, positions, normals, triangles);
    }
  });
}

void writeTextFile(const std::string& path, const std::string& text) {
  std::string why;
  if (!detail::writeFileAtomically(path, {{text.data(), text.size()}},
                                   detail::ParentFolder::kMustExist, &why))
    throw Error(ErrorCode::kIo, path + ": " + why);
}

}  // namespace isk
