#include "arrays.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "isk/core/error.hpp"

namespace isk::python {

void fail(const std::string& what, const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, what + ": " + message);
}

std::string shapeText(const py::array& array) {
  std::ostringstream text;
  text << "(";
  for (py::ssize_t i = 0; i < array.ndim(); ++i) {
    text << (i ? ", " : "") << array.shape(i);
  }
  text << (array.ndim() == 1 ? ",)" : ")");
  return text.str();
}

namespace {

std::string expectedShape(const std::vector<py::ssize_t>& shape) {
  static const char* names[] = {"N", "M", "K"};
  std::ostringstream text;
  text << "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    text << (i ? ", " : "");
    if (shape[i] >= 0) {
      text << shape[i];
    } else {
      text << names[i % 3];
    }
  }
  text << (shape.size() == 1 ? ",)" : ")");
  return text.str();
}

// `object` as an array of any dtype, its dtype kind among `kinds`, its
// shape matching `shape`.
py::array checkedArray(py::handle object, const std::string& what,
                       const std::vector<py::ssize_t>& shape,
                       const std::string& kinds, const char* kind_text) {
  py::array array = py::array::ensure(object);
  if (!array) {
    PyErr_Clear();
    fail(what, "expected an array, got " +
                   std::string(py::str(py::type::handle_of(object))));
  }
  const char kind = array.dtype().kind();
  if (kinds.find(kind) == std::string::npos) {
    fail(what, std::string("expected ") + kind_text + ", got dtype " +
                   std::string(py::str(array.dtype())));
  }
  bool ok = array.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; ok && i < shape.size(); ++i) {
    ok = shape[i] < 0 || array.shape(i) == shape[i];
  }
  if (!ok) {
    fail(what, "expected shape " + expectedShape(shape) + ", got " +
                   shapeText(array));
  }
  return array;
}

}  // namespace

FloatArray floatArray(py::handle object, const std::string& what,
                      std::vector<py::ssize_t> shape) {
  py::array array = checkedArray(object, what, shape, "fiub", "real numbers");
  return py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(
      array);
}

IntArray intArray(py::handle object, const std::string& what,
                  std::vector<py::ssize_t> shape) {
  py::array array = checkedArray(object, what, shape, "iu", "integers");
  // Through int64 so that values beyond int32 are named, not wrapped.
  auto wide =
      py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(
          array);
  if (!wide) {
    PyErr_Clear();
    fail(what, "cannot be read as 64-bit integers");
  }
  IntArray out(
      std::vector<py::ssize_t>(array.shape(), array.shape() + array.ndim()));
  const int64_t* in = wide.data();
  int32_t* dst = out.mutable_data();
  for (py::ssize_t i = 0; i < wide.size(); ++i) {
    if (in[i] < std::numeric_limits<int32_t>::min() ||
        in[i] > std::numeric_limits<int32_t>::max()) {
      fail(what, "value " + std::to_string(in[i]) + " at flat index " +
                     std::to_string(i) + " does not fit in 32 bits");
    }
    dst[i] = static_cast<int32_t>(in[i]);
  }
  return out;
}

Matrix3Xf matrix3Xf(py::handle object, const std::string& what,
                    py::ssize_t rows) {
  FloatArray array = floatArray(object, what, {rows, 3});
  const py::ssize_t n = array.shape(0);
  Matrix3Xf out(n, 3);
  const float* data = array.data();
  for (py::ssize_t r = 0; r < n; ++r) {
    for (int c = 0; c < 3; ++c) {
      const float value = data[3 * r + c];
      if (!std::isfinite(value)) {
        fail(what, "row " + std::to_string(r) + " is not finite (" +
                       std::to_string(value) + ")");
      }
      out(r, c) = value;
    }
  }
  return out;
}

FloatArray transformsArray(const TransformList& transforms) {
  FloatArray out({static_cast<py::ssize_t>(transforms.size()), py::ssize_t{4},
                  py::ssize_t{4}});
  float* dst = out.mutable_data();
  for (size_t j = 0; j < transforms.size(); ++j) {
    const Eigen::Matrix4f& m = transforms[j].matrix();
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) dst[16 * j + 4 * r + c] = m(r, c);
    }
  }
  return out;
}

TransformList transformList(py::handle object, const std::string& what,
                            int count) {
  FloatArray array = floatArray(object, what, {count, 4, 4});
  const float* data = array.data();
  TransformList out(count);
  for (int j = 0; j < count; ++j) {
    const float* m = data + 16 * j;
    if (m[12] != 0.f || m[13] != 0.f || m[14] != 0.f || m[15] != 1.f) {
      fail(what, "matrix " + std::to_string(j) +
                     ": the last row must be 0 0 0 1 (an affine transform)");
    }
    Eigen::Matrix4f matrix;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) matrix(r, c) = m[4 * r + c];
    }
    out[j].matrix() = matrix;
  }
  return out;
}

FloatArray ownedArray(Matrix3Xf&& matrix) {
  auto* owned = new Matrix3Xf(std::move(matrix));
  py::capsule owner(owned, [](void* p) { delete static_cast<Matrix3Xf*>(p); });
  return FloatArray({static_cast<py::ssize_t>(owned->rows()), py::ssize_t{3}},
                    owned->data(), owner);
}

FloatArray copiedArray(const Matrix3Xf& matrix) {
  FloatArray out({static_cast<py::ssize_t>(matrix.rows()), py::ssize_t{3}});
  if (matrix.size() > 0) {
    std::copy(matrix.data(), matrix.data() + matrix.size(), out.mutable_data());
  }
  return out;
}

}  // namespace isk::python
