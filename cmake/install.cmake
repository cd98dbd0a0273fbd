# The installable package (docs/install.md): `cmake --install build --prefix P` puts the `scan2model` command in
# P/bin, the core libraries in P/lib..., the public headers in P/include/scan2model, the Python package in
# P/lib/python3/dist-packages/scan2model, and scan2modelConfig.cmake with its version file and the exported
# targets scan2model::core (the maths core: registration and fitting), scan2model::registration,
# scan2model::fitting, scan2model::synthetic, scan2model::acquisition and scan2model::pipeline in
# P/lib.../cmake/scan2model. CPack builds a .deb of the same install (`cpack -G DEB` in the build folder).
include(CMakePackageConfigHelpers)
# `cmake --install` and cpack install what is built; they do not build every target first (the tests and
# benchmarks are not installed).
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)

add_library(s2m_core INTERFACE)
target_link_libraries(s2m_core INTERFACE s2m_fitting s2m_registration)
set_target_properties(s2m_core PROPERTIES EXPORT_NAME core)
foreach(library ${S2M_CORE_LIBRARIES})
  string(REPLACE "s2m_" "" export_name ${library})
  set_target_properties(${library} PROPERTIES EXPORT_NAME ${export_name})
endforeach()

install(TARGETS scan2model RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
install(TARGETS s2m_core ${S2M_CORE_LIBRARIES} EXPORT scan2modelTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development)
install(DIRECTORY registration fitting synthetic acquisition pipeline DESTINATION ${S2M_INSTALL_INCLUDEDIR}
        COMPONENT development FILES_MATCHING PATTERN "*.h")

set(S2M_CMAKE_INSTALL_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/scan2model")
install(EXPORT scan2modelTargets NAMESPACE scan2model:: DESTINATION ${S2M_CMAKE_INSTALL_DIR}
        COMPONENT development)
# The static libraries' private dependencies are link dependencies of every consumer: the config finds them
# (find_dependency). PCL, Open3D, OpenCV and libusb stay with the command and the edge libraries, which are not
# exported.
get_target_property(s2m_pipeline_links s2m_pipeline LINK_LIBRARIES)
if("MPI::MPI_CXX" IN_LIST s2m_pipeline_links)
  set(S2M_CONFIG_NEEDS_MPI ON)
else()
  set(S2M_CONFIG_NEEDS_MPI OFF)
endif()
configure_package_config_file(cmake/scan2modelConfig.cmake.in
                              "${PROJECT_BINARY_DIR}/scan2modelConfig.cmake"
                              INSTALL_DESTINATION ${S2M_CMAKE_INSTALL_DIR})
# 0.x: a minor version may change the interface.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/scan2modelConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/scan2modelConfig.cmake" "${PROJECT_BINARY_DIR}/scan2modelConfigVersion.cmake"
        DESTINATION ${S2M_CMAKE_INSTALL_DIR} COMPONENT development)

# The .deb: one package with the command, the Python module, the libraries and headers. Its dependencies are
# Debian's package names: those of the shared libraries the command and the module link (dpkg-shlibdeps),
# Python and NumPy for the module, and (recommended) the -dev packages a CMake consumer's find_package needs.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME scan2model)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Fits measured models to scanner point clouds (command, Python module, C++ libraries)")
set(CPACK_PACKAGE_CONTACT "scan2model maintainers")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
if(TARGET s2m_python)  # the module is built for one Python minor version (its ABI tag)
  math(EXPR s2m_python_next_minor "${Python3_VERSION_MINOR} + 1")
  set(CPACK_DEBIAN_PACKAGE_DEPENDS "python3 (>= ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}), python3 (<< "
                                   "${Python3_VERSION_MAJOR}.${s2m_python_next_minor}), python3-numpy")
  string(REPLACE ";" "" CPACK_DEBIAN_PACKAGE_DEPENDS "${CPACK_DEBIAN_PACKAGE_DEPENDS}")
endif()
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "libeigen3-dev, nlohmann-json3-dev, zlib1g-dev, libsqlite3-dev, libpugixml-dev")
# gzip: a few seconds (xz takes about a minute for the static libraries).
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip)
include(CPack)
