// NumPy arrays in and out of the isk types: every input is checked (kind of
// dtype, shape, integer range) with a message naming the argument, and
// every result is a new array that owns the C++ result without a copy where
// the result can be moved.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/rig/skeleton.hpp"

namespace isk::python {

namespace py = pybind11;

using FloatArray = py::array_t<float, py::array::c_style>;
using IntArray = py::array_t<int32_t, py::array::c_style>;

// Throws isk::Error(kInvalidArgument) with `what` (the argument's name)
// followed by `message`.
[[noreturn]] void fail(const std::string& what, const std::string& message);

// `object` as a C-contiguous float32 array of `ndim` dimensions whose sizes
// equal `shape` where that is >= 0 (-1: any). Any real or integer dtype is
// converted; anything else (strings, objects, complex) is an error.
FloatArray floatArray(py::handle object, const std::string& what,
                      std::vector<py::ssize_t> shape);
// The same for indices: integer dtypes only, values within int32.
IntArray intArray(py::handle object, const std::string& what,
                  std::vector<py::ssize_t> shape);

// "(3, 4)"
std::string shapeText(const py::array& array);

// #V by 3 float rows from a (V, 3) array; every value finite, else an error
// naming the first bad row.
Matrix3Xf matrix3Xf(py::handle object, const std::string& what,
                    py::ssize_t rows = -1);

// (J, 4, 4) float32 from transforms, row-major per matrix.
FloatArray transformsArray(const TransformList& transforms);
// Transforms from a (count, 4, 4) array whose last rows are 0 0 0 1.
TransformList transformList(py::handle object, const std::string& what,
                            int count);

// A (V, 3) float32 array owning `matrix` (moved, not copied).
FloatArray ownedArray(Matrix3Xf&& matrix);
// A (V, 3) float32 copy.
FloatArray copiedArray(const Matrix3Xf& matrix);

}  // namespace isk::python
