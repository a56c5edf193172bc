# `cmake --install`: libterravt and libterravt_compose (shared, with their SOVERSION links, and
# static: libterravt.a, libterravt_compose.a), the public headers, the GLSL
# contract (terravt/vt.glsl and the files it includes, under terravt/glsl/), the CMake package
# (terravtConfig.cmake, version file, targets in the terravt:: namespace) and a pkg-config file.
# Nothing else is installed: internal headers and libraries stay in the build tree.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

target_include_directories(terravt_api_headers INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
set_target_properties(terravt_api_headers PROPERTIES EXPORT_NAME headers)
install(TARGETS terravt_lib terravt_api_headers EXPORT terravtTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/terravt DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
  FILES_MATCHING PATTERN "*.h")
install(FILES ${PROJECT_BINARY_DIR}/include/terravt/version.h ${PROJECT_SOURCE_DIR}/include/terravt/vt.glsl
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/terravt)
# The GLSL that terravt/vt.glsl includes: the same files terravt's own shaders use.
install(FILES ${PROJECT_SOURCE_DIR}/shaders/vt_lookup.glsl ${PROJECT_SOURCE_DIR}/shaders/vt_lod.glsl
  ${PROJECT_SOURCE_DIR}/shaders/vt_sample.glsl DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/terravt/glsl)
install(FILES ${PROJECT_SOURCE_DIR}/shaders/shared/bridge.h ${PROJECT_SOURCE_DIR}/shaders/shared/hash.h
  ${PROJECT_SOURCE_DIR}/shaders/shared/page_table_entry.h ${PROJECT_SOURCE_DIR}/shaders/shared/vt_types.h
  ${PROJECT_SOURCE_DIR}/shaders/shared/feedback_types.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/terravt/glsl/shared)

set(TVT_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/terravt)
install(EXPORT terravtTargets NAMESPACE terravt:: DESTINATION ${TVT_CMAKE_DIR})
# Each further component is its own export set, loaded by the package only when asked for:
# libterravt_compose.so (COMPONENTS compose), libterravt.a (static), libterravt_compose.a (both).
install(TARGETS terravt_compose_lib EXPORT terravtComposeTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(EXPORT terravtComposeTargets NAMESPACE terravt:: DESTINATION ${TVT_CMAKE_DIR})
install(TARGETS terravt_static EXPORT terravtStaticTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(EXPORT terravtStaticTargets NAMESPACE terravt:: DESTINATION ${TVT_CMAKE_DIR})
install(TARGETS terravt_compose_static EXPORT terravtComposeStaticTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(EXPORT terravtComposeStaticTargets NAMESPACE terravt:: DESTINATION ${TVT_CMAKE_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/terravtConfig.cmake.in
  ${PROJECT_BINARY_DIR}/terravtConfig.cmake INSTALL_DESTINATION ${TVT_CMAKE_DIR})
# 0.x: minor versions may break the API, so only the same minor is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/terravtConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/terravtConfig.cmake ${PROJECT_BINARY_DIR}/terravtConfigVersion.cmake
  DESTINATION ${TVT_CMAKE_DIR})

file(RELATIVE_PATH TVT_PC_TO_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
configure_file(${PROJECT_SOURCE_DIR}/cmake/terravt.pc.in ${PROJECT_BINARY_DIR}/terravt.pc @ONLY)
configure_file(${PROJECT_SOURCE_DIR}/cmake/terravt_compose.pc.in ${PROJECT_BINARY_DIR}/terravt_compose.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/terravt.pc ${PROJECT_BINARY_DIR}/terravt_compose.pc
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
