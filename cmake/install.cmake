# `cmake --install BUILD --prefix P`: the public headers (with the generated version.h), the
# libraries, the CLI, the CMake package (find_package(flockmorph)) and the pkg-config files
# (docs/install.md). Included from CMakeLists.txt after the targets are defined.
include(CMakePackageConfigHelpers)

set(FM_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/flockmorph)
set(FM_PKGCONFIG_DIR ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

file(GLOB FM_PUBLIC_HEADERS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/include/flockmorph/*.h)
install(FILES ${FM_PUBLIC_HEADERS} ${FM_GENERATED_INCLUDE}/flockmorph/version.h
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/flockmorph)

# Two export sets, so that find_package(flockmorph COMPONENTS reader) loads only the reader and
# needs only zstd and zlib on the user's machine.
set(FM_ENGINE_TARGETS flockmorph)
if(FM_BUILD_SHARED)
  list(APPEND FM_ENGINE_TARGETS flockmorph_shared)
endif()
install(TARGETS ${FM_ENGINE_TARGETS} EXPORT flockmorphTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS flockmorph_reader EXPORT flockmorphReaderTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS flockmorph_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The CLI's manual page, with the one version (man/flockmorph.1.in).
configure_file(${PROJECT_SOURCE_DIR}/man/flockmorph.1.in ${CMAKE_BINARY_DIR}/package/flockmorph.1 @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/package/flockmorph.1 DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
install(EXPORT flockmorphTargets NAMESPACE flockmorph:: DESTINATION ${FM_CMAKE_DIR})
install(EXPORT flockmorphReaderTargets NAMESPACE flockmorph:: DESTINATION ${FM_CMAKE_DIR})

# flockmorphConfig.cmake finds again what the static libraries' link interfaces name, OpenVDB
# through the find module this build used (FM_OPENVDB_MODULE_DIR).
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/flockmorphConfig.cmake.in
  ${CMAKE_BINARY_DIR}/package/flockmorphConfig.cmake INSTALL_DESTINATION ${FM_CMAKE_DIR})
# Before 1.0 a minor version may break the API, so only the same major.minor is compatible.
write_basic_package_version_file(${CMAKE_BINARY_DIR}/package/flockmorphConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/package/flockmorphConfig.cmake ${CMAKE_BINARY_DIR}/package/flockmorphConfigVersion.cmake
        DESTINATION ${FM_CMAKE_DIR})

# pkg-config: the prefix is found from the .pc file's own place (${pcfiledir}), so the files are
# right for any --prefix given to cmake --install, not only CMAKE_INSTALL_PREFIX.
file(RELATIVE_PATH FM_PC_TO_PREFIX ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" FM_PC_TO_PREFIX "${FM_PC_TO_PREFIX}")
# What a program linking libflockmorph.a needs: the pkg-config modules (TBB and Imath because the
# OpenVDB adapters instantiate OpenVDB's templates, which call them), then the libraries without a
# .pc file (TetGen, Embree, OpenVDB), the C++ runtime and OpenMP. test_install links a program
# that pulls in every wing with exactly these. With the shared library installed they are private
# (pkg-config --static); without it -lflockmorph is the static library, so they are public.
set(FM_PC_REQUIRES "jansson libzstd zlib libpng libxxhash assimp tbb Imath")
if(FM_MPI)
  string(APPEND FM_PC_REQUIRES " ompi-c") # Open MPI's pkg-config module (Debian's libopenmpi-dev)
endif()
set(FM_PC_LIBS "-ltet -lembree3 -lopenvdb -lstdc++")
foreach(lib IN LISTS OpenMP_C_LIB_NAMES)
  string(APPEND FM_PC_LIBS " -l${lib}")
endforeach()
string(APPEND FM_PC_LIBS " -lm")
if(FM_BUILD_SHARED)
  set(FM_PC_PUBLIC_REQUIRES "")
  set(FM_PC_PUBLIC_LIBS "")
  set(FM_PC_PRIVATE_REQUIRES "${FM_PC_REQUIRES}")
  set(FM_PC_PRIVATE_LIBS "${FM_PC_LIBS}")
else()
  set(FM_PC_PUBLIC_REQUIRES "${FM_PC_REQUIRES}")
  set(FM_PC_PUBLIC_LIBS " ${FM_PC_LIBS}")
  set(FM_PC_PRIVATE_REQUIRES "")
  set(FM_PC_PRIVATE_LIBS "")
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/flockmorph.pc.in ${CMAKE_BINARY_DIR}/package/flockmorph.pc @ONLY)
configure_file(${PROJECT_SOURCE_DIR}/cmake/flockmorph_reader.pc.in ${CMAKE_BINARY_DIR}/package/flockmorph_reader.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/package/flockmorph.pc ${CMAKE_BINARY_DIR}/package/flockmorph_reader.pc
        DESTINATION ${FM_PKGCONFIG_DIR})
