# Debian package of fleetgw (CPack DEB): `cmake --build <build> --target package`.
#
# Contents: /usr/bin/fleetgw (from gateway/app), /etc/fleetgw/fleetgw.toml (conffile: dpkg keeps
# the technician's edits across upgrades), /lib/systemd/system/fleetgw.service, the CAN set-up
# helper and its networkd example, and docs/deployment.md. /var/lib/fleetgw and the `fleetgw`
# system user come from the maintainer scripts in deploy/debian/ (and StateDirectory=).
# Runtime dependencies are computed by dpkg-shlibdeps (package dpkg-dev) from the binary, so a
# cross-built package depends on the arm64 libraries it really links.
#
# Paths: /etc and /lib/systemd/system are absolute because that is where Debian expects them
# whatever the install prefix; `DESTDIR=/tmp/root cmake --install <build>` stages everything
# under /tmp/root for inspection.
set(FLEETGW_DEPLOY_DIR ${CMAKE_CURRENT_LIST_DIR})

install(FILES ${PROJECT_SOURCE_DIR}/config/fleetgw.toml DESTINATION /etc/fleetgw
        PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw.service DESTINATION /lib/systemd/system)
install(PROGRAMS ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw-can-setup
        DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/fleetgw)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/80-can.network
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)
install(FILES ${PROJECT_SOURCE_DIR}/docs/deployment.md DESTINATION ${CMAKE_INSTALL_DOCDIR})

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME fleetgw)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "fleetgw maintainers <fleetgw@example.org>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "MOTINOVA e-bike fleet telemetry gateway")
set(CPACK_PACKAGE_DESCRIPTION
    "Runs on the e-bike's IoT node: decodes the MOTINOVA CAN bus, records rides, faults, pack\n\
statistics, telemetry and lock events in SQLite, and syncs them to an MQTT broker.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # the build keeps debug info; the flash of an IoT node does not
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_SECTION net)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# adduser: the postinst creates the system user. The others serve the optional CAN helper and
# the technician.
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "iproute2")
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
