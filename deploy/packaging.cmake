# Debian package of fleetgw (CPack DEB): `cmake --build <build> --target package`.
#
# Contents: /usr/bin/fleetgw (from gateway/app), /etc/fleetgw/fleetgw.toml (conffile: dpkg keeps
# the technician's edits across upgrades), /lib/systemd/system/fleetgw.service, the CAN set-up
# helper and its networkd example, docs/deployment.md, the manual pages and the bash completion
# (/usr/share/bash-completion/completions/fleetgw), both generated from the CLI definitions.
# /var/lib/fleetgw and the `fleetgw` system user come from the maintainer scripts in
# deploy/debian/ (and StateDirectory=).
# Runtime dependencies are computed by dpkg-shlibdeps (package dpkg-dev) from the binary, so a
# cross-built package depends on the arm64 libraries it really links.
#
# Paths: /etc and /lib/systemd/system are absolute because that is where Debian expects them
# whatever the install prefix; `DESTDIR=/tmp/root cmake --install <build>` stages everything
# under /tmp/root for inspection.
set(FLEETGW_DEPLOY_DIR ${CMAKE_CURRENT_LIST_DIR})

# Shipped 0644 like any conffile (the default holds no secret); the postinst makes it
# root:fleetgw 0640 before a technician adds broker credentials.
install(FILES ${PROJECT_SOURCE_DIR}/config/fleetgw.toml DESTINATION /etc/fleetgw)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw.service DESTINATION /lib/systemd/system)
install(PROGRAMS ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw-can-setup
        DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/fleetgw)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/80-can.network
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)
install(FILES ${PROJECT_SOURCE_DIR}/docs/deployment.md DESTINATION ${CMAKE_INSTALL_DOCDIR})

# Debian policy: the copyright file and the changelog (gzip -9n: reproducible) in the doc dir.
install(FILES ${FLEETGW_DEPLOY_DIR}/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})
set(FLEETGW_CHANGELOG_GZ ${CMAKE_BINARY_DIR}/deploy/changelog.Debian.gz)
add_custom_command(
  OUTPUT ${FLEETGW_CHANGELOG_GZ}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/deploy
  COMMAND gzip -9nc ${FLEETGW_DEPLOY_DIR}/debian/changelog > ${FLEETGW_CHANGELOG_GZ}
  DEPENDS ${FLEETGW_DEPLOY_DIR}/debian/changelog
  VERBATIM)
add_custom_target(fleetgw_changelog ALL DEPENDS ${FLEETGW_CHANGELOG_GZ})
install(FILES ${FLEETGW_CHANGELOG_GZ} DESTINATION ${CMAKE_INSTALL_DOCDIR})

# Manual pages, generated from the CLI definitions by help2man running the built binaries (so
# not in a cross build, whose binaries do not run here).
if(NOT CMAKE_CROSSCOMPILING AND TARGET fleetgw-watch)
  find_program(FLEETGW_HELP2MAN help2man)
  if(FLEETGW_HELP2MAN)
    set(man_dir ${CMAKE_BINARY_DIR}/deploy/man)
    set(man_pages)
    foreach(page fleetgw fleetgw-run fleetgw-decode fleetgw-check-config fleetgw-status
                 fleetgw-command fleetgw-keygen fleetgw-db fleetgw-ride fleetgw-sim fleetgw-watch)
      list(APPEND man_pages ${man_dir}/${page}.1.gz)
    endforeach()
    add_custom_command(
      OUTPUT ${man_pages}
      COMMAND ${FLEETGW_DEPLOY_DIR}/man/make-man-pages.sh $<TARGET_FILE:fleetgw>
              $<TARGET_FILE:fleetgw-watch> ${PROJECT_VERSION} ${man_dir}
      DEPENDS fleetgw fleetgw-watch ${FLEETGW_DEPLOY_DIR}/man/make-man-pages.sh
      VERBATIM)
    add_custom_target(fleetgw_man_pages ALL DEPENDS ${man_pages})
    install(FILES ${man_pages} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
  else()
    message(STATUS "help2man not found: the package will have no manual pages")
  endif()
endif()

# Bash completion, printed by the built binary from its CLI definitions (`fleetgw completion
# bash`), so it follows every option added; likewise not in a cross build. Written to a
# temporary name first: a failing run leaves no stale script that looks up to date.
if(NOT CMAKE_CROSSCOMPILING)
  set(FLEETGW_COMPLETION ${CMAKE_BINARY_DIR}/deploy/bash-completion/fleetgw)
  add_custom_command(
    OUTPUT ${FLEETGW_COMPLETION}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/deploy/bash-completion
    COMMAND $<TARGET_FILE:fleetgw> completion bash > ${FLEETGW_COMPLETION}.tmp
    COMMAND ${CMAKE_COMMAND} -E rename ${FLEETGW_COMPLETION}.tmp ${FLEETGW_COMPLETION}
    DEPENDS fleetgw
    VERBATIM)
  add_custom_target(fleetgw_bash_completion ALL DEPENDS ${FLEETGW_COMPLETION})
  install(FILES ${FLEETGW_COMPLETION}
          DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME fleetgw)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "fleetgw maintainers <fleetgw@example.org>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "MOTINOVA e-bike fleet telemetry gateway")
# Lines of the long description stay under 80 characters (lintian).
set(CPACK_PACKAGE_DESCRIPTION
    "Runs on the e-bike's IoT node: decodes the MOTINOVA CAN bus, records rides,\n\
faults, pack statistics, telemetry and lock events in SQLite, and syncs them to\n\
an MQTT broker.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # the build keeps debug info; the flash of an IoT node does not
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_SECTION net)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# adduser: the postinst creates the system user. The others serve the optional CAN helper, the
# GNSS receiver ([gnss], through gpsd) and the technician.
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "iproute2, gpsd")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "can-utils, mosquitto-clients")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${FLEETGW_DEPLOY_DIR}/debian/conffiles ${FLEETGW_DEPLOY_DIR}/debian/postinst
    ${FLEETGW_DEPLOY_DIR}/debian/prerm ${FLEETGW_DEPLOY_DIR}/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)

# A cross build packages for the target: dpkg --print-architecture would name the build host.
if(CMAKE_CROSSCOMPILING)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE armhf)
  endif()
endif()

include(CPack)
