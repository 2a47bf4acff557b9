# Install rules: the commands, the C library with its header, pkg-config file and CMake package, the data files the
# runtime looks for in PREFIX/share/egopd, and the Python module (when a Python 3 interpreter is found).
include(CMakePackageConfigHelpers)

install(TARGETS egopd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(FILES ${CMAKE_SOURCE_DIR}/data/templates/synthetic_right_hand.json DESTINATION ${CMAKE_INSTALL_DATADIR}/egopd/templates)

if(EGOPD_BUILD_SHARED)
  install(TARGETS egopd_shared EXPORT egopdTargets
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(FILES ${CMAKE_SOURCE_DIR}/include/egopd.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

  set(egopd_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/egopd)
  install(EXPORT egopdTargets NAMESPACE egopd:: DESTINATION ${egopd_cmake_dir})
  configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/egopdConfig.cmake.in
                                ${CMAKE_BINARY_DIR}/generated/egopdConfig.cmake INSTALL_DESTINATION ${egopd_cmake_dir})
  write_basic_package_version_file(${CMAKE_BINARY_DIR}/generated/egopdConfigVersion.cmake
                                   VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
  install(FILES ${CMAKE_BINARY_DIR}/generated/egopdConfig.cmake ${CMAKE_BINARY_DIR}/generated/egopdConfigVersion.cmake
          DESTINATION ${egopd_cmake_dir})

  # pkg-config: the prefix is the one given to `cmake --install --prefix P` (CMAKE_INSTALL_PREFIX at install time).
  install(CODE "
    set(CMAKE_INSTALL_PREFIX \"\${CMAKE_INSTALL_PREFIX}\")
    set(CMAKE_INSTALL_LIBDIR \"${CMAKE_INSTALL_LIBDIR}\")
    set(CMAKE_INSTALL_INCLUDEDIR \"${CMAKE_INSTALL_INCLUDEDIR}\")
    set(PROJECT_VERSION \"${PROJECT_VERSION}\")
    configure_file(\"${CMAKE_SOURCE_DIR}/cmake/egopd.pc.in\" \"${CMAKE_BINARY_DIR}/generated/egopd.pc\" @ONLY)
  ")
  install(FILES ${CMAKE_BINARY_DIR}/generated/egopd.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

  # The Python module (python/egopd) finds the library at PREFIX/lib*/libegopd.so.0 relative to itself.
  find_package(Python3 COMPONENTS Interpreter)
  if(Python3_FOUND)
    # Debian's python3 searches /usr/local/lib/python3.X/dist-packages; other prefixes go on PYTHONPATH.
    set(EGOPD_PYTHON_DIR "lib/python${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}/dist-packages" CACHE STRING
        "Where `cmake --install` puts the Python module egopd (relative to the prefix)")
    install(DIRECTORY ${CMAKE_SOURCE_DIR}/python/egopd DESTINATION ${EGOPD_PYTHON_DIR}
            PATTERN "__pycache__" EXCLUDE)
  endif()
endif()
