# The README's "link and deform" code block must be samples/link-and-deform/
# main.cpp verbatim: the block sits between the two marker lines
#   <!-- BEGIN samples/link-and-deform/main.cpp -->
#   <!-- END samples/link-and-deform/main.cpp -->
# as a ```cpp fence. cmake -DSOURCE_DIR=... -P readme_sample_check.cmake
cmake_minimum_required(VERSION 3.20)
set(name "samples/link-and-deform/main.cpp")
file(READ "${SOURCE_DIR}/README.md" readme)
file(READ "${SOURCE_DIR}/${name}" sample)
set(begin "<!-- BEGIN ${name} -->\n```cpp\n")
set(end "```\n<!-- END ${name} -->")
string(FIND "${readme}" "${begin}" first)
string(FIND "${readme}" "${end}" last)
if(first LESS 0 OR last LESS 0)
  message(FATAL_ERROR "README.md lacks the block between the markers of ${name}")
endif()
string(LENGTH "${begin}" begin_length)
math(EXPR start "${first} + ${begin_length}")
math(EXPR length "${last} - ${start}")
if(length LESS 0)
  message(FATAL_ERROR "README.md: the END marker of ${name} comes before BEGIN")
endif()
string(SUBSTRING "${readme}" ${start} ${length} block)
if(NOT block STREQUAL sample)
  message(FATAL_ERROR "README.md's block differs from ${name}: copy the file "
                      "into the block verbatim")
endif()
string(LENGTH "${sample}" sample_length)
message(STATUS "README.md block equals ${name} (${sample_length} characters)")
