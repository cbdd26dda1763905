# RiloInstall: `cmake --install` rules and the CPack Debian package.
#
#   <prefix>/bin/rilod, <prefix>/bin/rilo
#   <etc>/rilo/rilod.yaml                      default configuration (replay demo)
#   <etc>/rilo/rilod-hardware.yaml             hardware example
#   <prefix>/lib/systemd/system/rilod.service
#   <prefix>/lib/sysusers.d/rilo.conf          the rilo user and group
#   <prefix>/lib/udev/rules.d/99-rilo.rules    SPI/I2C/GPIO nodes for group rilo
#   <prefix>/share/rilo/recordings/office-demo the demo recording (if committed)
#   <prefix>/share/doc/rilo/...                READMEs
#
# <etc> is /etc when the prefix is /usr (the package, and GNUInstallDirs'
# rule), else <prefix>/etc. Paths inside the installed files follow the
# prefix: the unit's ExecStart= and --config, and the demo configuration's
# relative paths (rewritten to absolute paths into share/rilo). This happens
# at install time, so `cmake --install build --prefix X` and cpack agree.
#
# Include from the top-level CMakeLists.txt (anywhere after project()): the
# install rules for the executables are deferred to the end of the top-level
# directory, so the targets exist whichever line includes this file.
#
#   cmake --install build --prefix /usr/local     # or: sudo cmake --install build --prefix /usr
#   (cd build && cpack -G DEB)                    # rilo_<version>_<arch>.deb
include_guard(GLOBAL)
include(GNUInstallDirs)

set(RILO_INSTALL_COMPONENT rilo)

# --- executables (deferred: they are defined in subdirectories) ------------------
function(rilo_install_executables)
  foreach(exe rilod rilo)
    if(TARGET ${exe})
      install(TARGETS ${exe} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT ${RILO_INSTALL_COMPONENT})
    endif()
  endforeach()
  if(NOT TARGET rilod)
    message(STATUS "RiloInstall: no rilod target (service/rilod/main.cpp missing): not installed")
  endif()
endfunction()
cmake_language(DEFER DIRECTORY ${PROJECT_SOURCE_DIR} CALL rilo_install_executables)

# --- files whose content depends on the install prefix ---------------------------
# Variables for the install-time code below (bracket arguments are not expanded
# at configure time).
install(CODE "set(RILO_SOURCE_DIR [[${PROJECT_SOURCE_DIR}]])
set(RILO_STAGE_DIR [[${PROJECT_BINARY_DIR}/install-stage]])" COMPONENT ${RILO_INSTALL_COMPONENT})
install(CODE [[
  if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
    set(_rilo_etc "/etc/rilo")
  else()
    set(_rilo_etc "${CMAKE_INSTALL_PREFIX}/etc/rilo")
  endif()
  set(_rilo_share "${CMAKE_INSTALL_PREFIX}/share/rilo")
  file(MAKE_DIRECTORY "${RILO_STAGE_DIR}")

  # systemd unit: ExecStart= and --config follow the prefix.
  file(READ "${RILO_SOURCE_DIR}/systemd/rilod.service" _rilo_unit)
  string(REPLACE "/usr/bin/rilod" "${CMAKE_INSTALL_PREFIX}/bin/rilod" _rilo_unit "${_rilo_unit}")
  string(REPLACE "/etc/rilo/rilod.yaml" "${_rilo_etc}/rilod.yaml" _rilo_unit "${_rilo_unit}")
  file(WRITE "${RILO_STAGE_DIR}/rilod.service" "${_rilo_unit}")
  file(INSTALL DESTINATION "${CMAKE_INSTALL_PREFIX}/lib/systemd/system" TYPE FILE
       PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ FILES "${RILO_STAGE_DIR}/rilod.service")

  # Default configuration: the demo recording moves to share/rilo/recordings,
  # relative paths become absolute (the installed file is not next to tests/).
  file(READ "${RILO_SOURCE_DIR}/config/rilod.yaml" _rilo_config)
  string(REPLACE "../tests/data/" "${_rilo_share}/recordings/" _rilo_config "${_rilo_config}")
  string(REPLACE "# Relative paths are resolved against the directory of THIS file (config/),
# so the demo runs from a source checkout. The installed copy
# (/etc/rilo/rilod.yaml) has absolute paths into /usr/share/rilo."
                 "# Installed copy: the demo recording is in ${_rilo_share}/recordings.
# Relative paths would resolve against this file's directory."
                 _rilo_config "${_rilo_config}")
  file(WRITE "${RILO_STAGE_DIR}/rilod.yaml" "${_rilo_config}")
  file(INSTALL DESTINATION "${_rilo_etc}" TYPE FILE
       PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ
       FILES "${RILO_STAGE_DIR}/rilod.yaml" "${RILO_SOURCE_DIR}/config/rilod-hardware.yaml")
]] COMPONENT ${RILO_INSTALL_COMPONENT})

# --- prefix-independent files ----------------------------------------------------
install(FILES ${PROJECT_SOURCE_DIR}/systemd/rilo.sysusers
        DESTINATION lib/sysusers.d RENAME rilo.conf COMPONENT ${RILO_INSTALL_COMPONENT})
install(FILES ${PROJECT_SOURCE_DIR}/systemd/99-rilo.rules
        DESTINATION lib/udev/rules.d COMPONENT ${RILO_INSTALL_COMPONENT})
if(EXISTS ${PROJECT_SOURCE_DIR}/tests/data/office-demo)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/tests/data/office-demo
          DESTINATION ${CMAKE_INSTALL_DATADIR}/rilo/recordings COMPONENT ${RILO_INSTALL_COMPONENT})
else()
  message(STATUS "RiloInstall: tests/data/office-demo missing: the demo recording is not installed")
endif()
foreach(doc README.md config/README.md systemd/README.md)
  if(EXISTS ${PROJECT_SOURCE_DIR}/${doc})
    get_filename_component(_rilo_doc_dir ${doc} DIRECTORY)
    install(FILES ${PROJECT_SOURCE_DIR}/${doc}
            DESTINATION ${CMAKE_INSTALL_DOCDIR}/${_rilo_doc_dir} COMPONENT ${RILO_INSTALL_COMPONENT})
  endif()
endforeach()

# --- CPack: Debian package -------------------------------------------------------
set(CPACK_PACKAGE_NAME rilo)
set(CPACK_PACKAGE_VENDOR "rilo project")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Ranging-inertial localization service (UWB + IMU, DDS output)")
set(CPACK_PACKAGE_DESCRIPTION
    "rilod fuses UWB ranging (DWM3000) with an IMU (BMI263) in an incremental smoother and publishes the pose over DDS as ROS 2 messages. Includes the rilo tool, a systemd unit, configuration and a demo recording.")
set(CPACK_PACKAGE_CONTACT "rilo maintainers <rilo@example.org>")
set(CPACK_GENERATOR DEB)
# Absolute destinations (/etc/rilo) must land in the staging tree, never in the
# build machine's /etc: install through DESTDIR with the package's prefix.
set(CPACK_SET_DESTDIR ON)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "rilo maintainers <rilo@example.org>")
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# Library dependencies from dpkg-shlibdeps; systemd for the unit, sysusers and udev.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd")
# Maintainer scripts (create the user, reload udev and systemd) and the
# configuration files dpkg must not overwrite on upgrade.
set(_rilo_conffiles ${PROJECT_BINARY_DIR}/cpack/conffiles)
file(WRITE ${_rilo_conffiles} "/etc/rilo/rilod.yaml\n/etc/rilo/rilod-hardware.yaml\n")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/systemd/debian/postinst
    ${PROJECT_SOURCE_DIR}/systemd/debian/prerm
    ${PROJECT_SOURCE_DIR}/systemd/debian/postrm
    ${_rilo_conffiles})
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
