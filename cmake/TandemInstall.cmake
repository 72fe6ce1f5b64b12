# Installing Tandem as a library: `cmake --install build/release --prefix P`
# puts the tandem and tandem-view executables in P/bin, the public header
# in P/include/tandem/, the static libraries in P/lib and a CMake package in
# P/lib/cmake/Tandem, so that an application does
#
#   find_package(Tandem CONFIG REQUIRED)
#   target_link_libraries(app PRIVATE Tandem::tandem)
#
# Tandem::tandem is the API of <tandem/tandem.h>. The engine's libraries it
# is built on are static, so they are installed and exported too (as
# Tandem::tandem_core, ...; for linking only, their headers are not
# installed), and TandemConfig.cmake finds what they link against.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(tandem_exported_libraries
  tandem_api tandem_tracer tandem_backends tandem_backend_cpu tandem_backend_cuda
  tandem_cpu_loops tandem_scenes tandem_sync tandem_accstruc tandem_core tandem_kernel
  # Interface targets the static libraries name in their link interfaces.
  tandem_stb tandem_warnings)
if(TARGET tandem_cuda_device)
  list(APPEND tandem_exported_libraries tandem_cuda_device)
endif()
install(TARGETS ${tandem_exported_libraries} EXPORT TandemTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  FILE_SET HEADERS DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT TandemTargets NAMESPACE Tandem:: FILE TandemTargets.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/Tandem)

set(tandem_executables tandem)
if(TARGET tandem-view)
  list(APPEND tandem_executables tandem-view)
endif()
install(TARGETS ${tandem_executables} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# Where this build found nvcc, so that the package's find_dependency
# (CUDAToolkit) finds the same toolkit's static runtime.
set(TANDEM_CUDA_TOOLKIT_ROOT "")
if(TANDEM_BUILD_CUDA AND CUDAToolkit_BIN_DIR)
  get_filename_component(TANDEM_CUDA_TOOLKIT_ROOT "${CUDAToolkit_BIN_DIR}" DIRECTORY)
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/TandemConfig.cmake.in
  ${PROJECT_BINARY_DIR}/TandemConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/Tandem)
# 0.x: a new minor version may change the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/TandemConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/TandemConfig.cmake ${PROJECT_BINARY_DIR}/TandemConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/Tandem)
