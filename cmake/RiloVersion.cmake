# rilo_version: an interface library whose header rilo_version.h gives
# RILO_VERSION, RILO_GIT_DESCRIBE and RILO_VERSION_TEXT (cmake/write_version.cmake),
# refreshed by every build. Programs print it on --version; rilo report
# records it (a report names the build that made it, not the checkout it ran in).
set(RILO_VERSION_DIR ${PROJECT_BINARY_DIR}/generated/version)
add_custom_target(rilo_version_header
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${PROJECT_SOURCE_DIR} -DVERSION=${PROJECT_VERSION}
          -DOUT=${RILO_VERSION_DIR}/rilo_version.h -P ${PROJECT_SOURCE_DIR}/cmake/write_version.cmake
  BYPRODUCTS ${RILO_VERSION_DIR}/rilo_version.h
  COMMENT "Version header (git describe)"
  VERBATIM)
add_library(rilo_version INTERFACE)
target_include_directories(rilo_version INTERFACE ${RILO_VERSION_DIR})
add_dependencies(rilo_version rilo_version_header)
