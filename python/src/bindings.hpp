// The parts of the module, each registering its classes and functions.
#pragma once

#include <pybind11/pybind11.h>

namespace isk::python {

void registerRig(pybind11::module_& m);       // rig.cpp
void registerSkinners(pybind11::module_& m);  // skinners.cpp
void registerQuality(pybind11::module_& m);   // quality.cpp

}  // namespace isk::python
