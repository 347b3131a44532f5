# The Python module `vtsim` (src/python, docs/python.md): pybind11 over vtsim_lib, built by this
# CMake and installed by `cmake --install` into PREFIX/VTSIM_PYTHON_INSTALL_DIR.
#
# The interpreter: Python3_EXECUTABLE when given, else /usr/bin/python3 when it exists (Debian's
# python3-numpy and python3-pandas install for it; a pyenv or venv python first on PATH would
# build a module that interpreter's numpy never sees), else the first python3 found.
# Off in sanitizer builds (a sanitized module needs its runtime preloaded into python).
if(VTSIM_SANITIZE)
  set(_vtsim_python_default OFF)
else()
  set(_vtsim_python_default ON)
endif()
option(VTSIM_BUILD_PYTHON "Build the Python module (pybind11; Debian: pybind11-dev python3-dev python3-numpy)"
       ${_vtsim_python_default})
if(NOT VTSIM_BUILD_PYTHON)
  return()
endif()
if(NOT Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
  set(Python3_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "The Python the module is built for")
endif()
find_package(Python3 COMPONENTS Interpreter Development.Module)
if(Python3_FOUND)
  find_package(pybind11 CONFIG)
endif()
if(NOT Python3_FOUND OR NOT pybind11_FOUND)
  message(WARNING "Python 3 development files or pybind11 not found (Debian: python3-dev pybind11-dev): building "
                  "without the Python module (-DVTSIM_BUILD_PYTHON=OFF silences this)")
  set(VTSIM_BUILD_PYTHON OFF)  # for this configure only: installing them later builds the module
  return()
endif()
message(STATUS "vtsim Python module for ${Python3_EXECUTABLE} (Python ${Python3_VERSION}, pybind11 ${pybind11_VERSION})")

# The static library goes into a shared object: position-independent code. -fno-semantic-interposition
# keeps GCC's inlining and calls within the library as they are without -fPIC (no global function of
# the library is meant to be interposed).
set_target_properties(vtsim_lib PROPERTIES POSITION_INDEPENDENT_CODE ON)
target_compile_options(vtsim_lib PRIVATE $<$<CXX_COMPILER_ID:GNU>:-fno-semantic-interposition>)

# NO_EXTRAS: no LTO and no strip (the library is not LTO-compiled; a stripped module gives no stack).
pybind11_add_module(vtsim_python MODULE NO_EXTRAS ${PROJECT_SOURCE_DIR}/src/python/vtsim_module.cpp)
set_target_properties(vtsim_python PROPERTIES OUTPUT_NAME vtsim LIBRARY_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/python)
target_link_libraries(vtsim_python PRIVATE vtsim_lib)
vtsim_warnings(vtsim_python)
# pybind11 2.10's clear_patients (detail/class.h) moves a std::vector GCC 12 cannot prove non-null
# once inlined: a -Wnull-dereference in pybind11's own code, not ours.
target_compile_options(vtsim_python PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-null-dereference>)
vtsim_cold_code(vtsim_python)  # binding code, no hot loop: -O1 halves its compile time
add_dependencies(vtsim_python vtsim_image)

set(VTSIM_PYTHON_INSTALL_DIR "${CMAKE_INSTALL_LIBDIR}/python${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}/site-packages"
    CACHE STRING "Where `cmake --install` puts the module, relative to the prefix")
install(TARGETS vtsim_python LIBRARY DESTINATION ${VTSIM_PYTHON_INSTALL_DIR})
