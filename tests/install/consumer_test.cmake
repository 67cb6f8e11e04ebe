# Installs isk into a fresh prefix and builds samples/link-and-deform against
# the installed package, both ways, then runs each build on the procedural
# cylinder and checks what it prints and writes:
#   1. CMake, find_package(isk CONFIG), isk::io (the shared libraries);
#   2. pkg-config (isk-io.pc, which requires isk.pc): `pkg-config --cflags
#      --libs isk-io` (shared), and the same object linked with
#      `pkg-config --static --libs isk-io`;
#   3. CMake with ISK_USE_STATIC_LIBS=ON (isk::io_static, isk::isk_static).
# The two static programs run after the shared library is deleted from the
# prefix, so they must be static.
# cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DLIBDIR=...
#       -DCXX=... -DGENERATOR=... -DVERSION=... [-DPKG_CONFIG=...] -P consumer_test.cmake
cmake_minimum_required(VERSION 3.20)
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR LIBDIR CXX GENERATOR VERSION)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "consumer_test.cmake: -D${var}=... missing")
  endif()
endforeach()

# run_step(WHAT COMMAND... [WORKING_DIRECTORY DIR])
function(run_step what)
  cmake_parse_arguments(PARSE_ARGV 1 step "" "WORKING_DIRECTORY" "")
  set(dir "${CMAKE_CURRENT_BINARY_DIR}")
  if(step_WORKING_DIRECTORY)
    set(dir "${step_WORKING_DIRECTORY}")
  endif()
  execute_process(COMMAND ${step_UNPARSED_ARGUMENTS} WORKING_DIRECTORY "${dir}"
                  RESULT_VARIABLE rc
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${step_UNPARSED_ARGUMENTS}\n${out}\n${err}")
  endif()
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

# What one consumer run must show: every frame printed, the bind pose (frame
# 0) reproducing the rest mesh, the bent last frame moving the cylinder's tip
# and stopping vertices at a contact, the same frames as the first program,
# and an OBJ holding every vertex.
function(check_run label exe)
  set(run_dir "${WORK_DIR}/run-${label}")
  file(MAKE_DIRECTORY "${run_dir}")
  set(obj "${run_dir}/link-and-deform.obj")
  run_step("running the ${label} consumer" "${exe}" WORKING_DIRECTORY "${run_dir}")
  message(STATUS "${label}:\n${step_output}")
  set(text "${step_output}")
  if(NOT text MATCHES "builtin:cylinder: ([0-9]+) vertices")
    message(FATAL_ERROR "${label}: no vertex count in the output")
  endif()
  set(vertices ${CMAKE_MATCH_1})
  foreach(frame 0 1 2 3 4)
    if(NOT text MATCHES "frame ${frame}  t [0-9.]+ s  max displacement ([0-9.e+-]+)  contacts ([0-9]+)")
      message(FATAL_ERROR "${label}: frame ${frame} missing from the output")
    endif()
    set(moved_${frame} ${CMAKE_MATCH_1})
    set(contacts_${frame} ${CMAKE_MATCH_2})
  endforeach()
  # Frame 0 is the bind pose: within 1e-4 model units (the cylinder is 8
  # long); frame 4 bends its joint 90 degrees: the tip moves by several
  # model units.
  if(NOT moved_0 LESS 1e-4)
    message(FATAL_ERROR "${label}: bind pose moved vertices by ${moved_0}")
  endif()
  if(NOT moved_4 GREATER 2)
    message(FATAL_ERROR "${label}: the bent frame moved vertices by only ${moved_4}")
  endif()
  # Bent by 90 degrees, the fold stops vertices on its contact surface.
  if(NOT contacts_4 GREATER 0)
    message(FATAL_ERROR "${label}: no contact vertex in the bent frame")
  endif()
  # Every build runs the same library on the same device: the same output.
  string(REGEX MATCHALL "frame [^\n]*" frames "${text}")
  if(DEFINED first_frames AND NOT first_frames STREQUAL frames)
    message(FATAL_ERROR "${label}: frames differ from the first build's:\n"
                        "${frames}\nvs\n${first_frames}")
  endif()
  set(first_frames "${frames}" PARENT_SCOPE)
  file(STRINGS "${obj}" vertex_lines REGEX "^v ")
  list(LENGTH vertex_lines written)
  if(NOT written EQUAL vertices)
    message(FATAL_ERROR "${label}: ${obj} holds ${written} vertices, not ${vertices}")
  endif()
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")
run_step("cmake --install" "${CMAKE_COMMAND}" --install "${BUILD_DIR}"
         --prefix "${prefix}")
foreach(file include/isk/implicit_skinner.hpp include/isk/cl/runtime.hpp
             include/isk/io/import.hpp include/isk/core/types.hpp
             ${LIBDIR}/libisk.a ${LIBDIR}/libisk.so
             ${LIBDIR}/libisk_io.a ${LIBDIR}/libisk_io.so
             ${LIBDIR}/cmake/isk/isk-config.cmake
             ${LIBDIR}/cmake/isk/isk-config-version.cmake
             ${LIBDIR}/pkgconfig/isk.pc ${LIBDIR}/pkgconfig/isk-io.pc)
  if(NOT EXISTS "${prefix}/${file}")
    message(FATAL_ERROR "cmake --install did not install ${file}")
  endif()
endforeach()

set(sample "${SOURCE_DIR}/samples/link-and-deform")
set(configure "${CMAKE_COMMAND}" -G "${GENERATOR}" -S "${sample}"
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_COMPILER=${CXX}"
    "-DCMAKE_PREFIX_PATH=${prefix}" -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON)

# 1. CMake, shared.
run_step("configuring the CMake consumer" ${configure} -B "${WORK_DIR}/cmake-shared")
run_step("building the CMake consumer" "${CMAKE_COMMAND}" --build "${WORK_DIR}/cmake-shared")
check_run(cmake-shared "${WORK_DIR}/cmake-shared/isk-link-and-deform")

# 2. pkg-config, shared (the prefix is found from the .pc file's place).
if(NOT PKG_CONFIG)
  find_program(PKG_CONFIG NAMES pkgconf pkg-config REQUIRED)
endif()
set(ENV{PKG_CONFIG_PATH} "${prefix}/${LIBDIR}/pkgconfig")
run_step("pkg-config --modversion isk" "${PKG_CONFIG}" --modversion isk)
string(STRIP "${step_output}" pc_version)
if(NOT pc_version VERSION_EQUAL VERSION)
  message(FATAL_ERROR "isk.pc says version ${pc_version}, the project ${VERSION}")
endif()
run_step("pkg-config --cflags --libs isk-io" "${PKG_CONFIG}" --cflags --libs isk-io)
separate_arguments(pc_flags UNIX_COMMAND "${step_output}")
# Its include folder must be the prefix's, however pkg-config spells it.
set(pc_include "")
foreach(flag IN LISTS pc_flags)
  if(flag MATCHES "^-I(.*)$")
    get_filename_component(dir "${CMAKE_MATCH_1}" REALPATH)
    if(EXISTS "${dir}/isk/implicit_skinner.hpp")
      set(pc_include "${dir}")
    endif()
  endif()
endforeach()
get_filename_component(prefix_include "${prefix}/include" REALPATH)
if(NOT pc_include STREQUAL prefix_include)
  message(FATAL_ERROR "isk.pc's include folder is not ${prefix_include}: ${pc_flags}")
endif()
run_step("compiling the pkg-config consumer" "${CXX}" -std=c++17 -O1
         -c "${sample}/main.cpp" -o "${WORK_DIR}/main.o" ${pc_flags})
run_step("linking the pkg-config consumer" "${CXX}" "${WORK_DIR}/main.o"
         -o "${WORK_DIR}/pkg-config-shared" ${pc_flags}
         "-Wl,-rpath,${prefix}/${LIBDIR}")
check_run(pkg-config-shared "${WORK_DIR}/pkg-config-shared")
# The same object linked statically: `pkg-config --static` lists the
# private libraries, with libisk_io.a and libisk.a named by their paths.
run_step("pkg-config --static --libs isk-io" "${PKG_CONFIG}" --static --libs isk-io)
separate_arguments(pc_static UNIX_COMMAND "${step_output}")
list(TRANSFORM pc_static REPLACE "^-lisk$" "${prefix}/${LIBDIR}/libisk.a")
list(TRANSFORM pc_static REPLACE "^-lisk_io$" "${prefix}/${LIBDIR}/libisk_io.a")
run_step("linking the static pkg-config consumer" "${CXX}" "${WORK_DIR}/main.o"
         -o "${WORK_DIR}/pkg-config-static" ${pc_static})

# 3. CMake, static.
run_step("configuring the static CMake consumer" ${configure}
         -B "${WORK_DIR}/cmake-static" -DISK_USE_STATIC_LIBS=ON)
run_step("building the static CMake consumer" "${CMAKE_COMMAND}" --build "${WORK_DIR}/cmake-static")

# The static programs run with the shared library gone from the prefix.
file(GLOB shared_libs "${prefix}/${LIBDIR}/libisk.so*" "${prefix}/${LIBDIR}/libisk_io.so*")
file(REMOVE ${shared_libs})
check_run(cmake-static "${WORK_DIR}/cmake-static/isk-link-and-deform")
check_run(pkg-config-static "${WORK_DIR}/pkg-config-static")
message(STATUS "installed package consumed four ways: cmake-shared, pkg-config-shared, cmake-static, pkg-config-static")
