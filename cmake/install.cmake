# `cmake --install BUILD --prefix P` (docs/embedding.md): the CLI in bin, the image module in
# lib/vtsim, the static library vtsim_lib with its public headers (include/vtsim, the src/ layout:
# #include "sim/run/replay.h"), a package config for find_package(vtsim) that defines vtsim::lib,
# and the standard traces in share/vtsim/traces.
include(CMakePackageConfigHelpers)

install(TARGETS vtsim RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS vtsim_image LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/vtsim)
install(TARGETS vtsim_lib EXPORT vtsimTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/vtsim)
# Every header of the library's layers; not the CLI's, and not core/toml_text.h (toml++ is a
# private dependency: no installed header may include it).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/src/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/vtsim
  FILES_MATCHING PATTERN "*.h"
  PATTERN "cli" EXCLUDE
  PATTERN "image_module" EXCLUDE
  PATTERN "toml_text.h" EXCLUDE)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/traces/ DESTINATION ${CMAKE_INSTALL_DATADIR}/vtsim/traces
  FILES_MATCHING PATTERN "*.csv")
install(FILES ${PROJECT_SOURCE_DIR}/tests/data/town_walk.csv DESTINATION ${CMAKE_INSTALL_DATADIR}/vtsim/traces)

install(EXPORT vtsimTargets NAMESPACE vtsim:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/vtsim)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/vtsimConfig.cmake.in
  ${PROJECT_BINARY_DIR}/vtsimConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/vtsim)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/vtsimConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/vtsimConfig.cmake ${PROJECT_BINARY_DIR}/vtsimConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/vtsim)
