// The extension isk._isk (docs/python.md): isk::Error as the Python
// exceptions isk.Error and isk.InvalidArgumentError, then each part's
// classes and functions.
#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "isk/core/error.hpp"

namespace py = pybind11;

namespace {

// Created once with the module and kept for the process: the translator
// below runs after the module's dict may be gone.
PyObject* error_type = nullptr;
PyObject* invalid_argument_type = nullptr;

void raise(const isk::Error& e) {
  PyObject* type = e.code() == isk::ErrorCode::kInvalidArgument
                       ? invalid_argument_type
                       : error_type;
  py::object instance = py::reinterpret_borrow<py::object>(type)(e.what());
  instance.attr("code") = isk::errorCodeName(e.code());
  instance.attr("cl_status") = e.clStatus();
  PyErr_SetObject(type, instance.ptr());
}

}  // namespace

PYBIND11_MODULE(_isk, m) {
  m.doc() =
      "Implicit skinning (Vaillant et al. 2013) on OpenCL: the isk C++ "
      "library from Python.";

  error_type = PyErr_NewExceptionWithDoc(
      "isk.Error",
      "An isk::Error: .code names its kind ('invalid_argument', 'io', "
      "'malformed_asset', 'no_device', 'opencl', 'internal', "
      "'limit_exceeded'), .cl_status the OpenCL status of an 'opencl' error.",
      PyExc_RuntimeError, nullptr);
  py::tuple bases =
      py::make_tuple(py::handle(error_type), py::handle(PyExc_ValueError));
  invalid_argument_type = PyErr_NewExceptionWithDoc(
      "isk.InvalidArgumentError",
      "An isk::Error with code 'invalid_argument': a malformed argument "
      "(shape, dtype, NaN, index out of range, ...). Also a ValueError.",
      bases.ptr(), nullptr);
  m.attr("Error") = py::handle(error_type);
  m.attr("InvalidArgumentError") = py::handle(invalid_argument_type);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const isk::Error& e) {
      raise(e);
    }
  });

  isk::python::registerRig(m);
  isk::python::registerSkinners(m);
  isk::python::registerQuality(m);
}
