# Debian packages (CPack DEB, one per component): `cmake --build <build> --target package`.
#
# fleetgw (component fleetgw), the IoT node's: /usr/bin/fleetgw and fleetgw-watch (from
# gateway/cli and gateway/tools/operator), /etc/fleetgw/fleetgw.toml (conffile: dpkg keeps the
# technician's edits across upgrades), /lib/systemd/system/fleetgw.service, the CAN set-up
# helper and its networkd example, docs/deployment.md, the manual pages and the bash completion
# (/usr/share/bash-completion/completions/fleetgw), both generated from the CLI definitions.
# /var/lib/fleetgw and the `fleetgw` system user come from the maintainer scripts in
# deploy/debian/ (and StateDirectory=).
# fleetgw-ingest (component fleetgw-ingest), a backend host's, built when libpq is found:
# /usr/bin/fleetgw-ingest, fleetgw-ingest.service (disabled), /etc/fleetgw-ingest/ingest.env
# (conffile), fleetgw-ingest(1), docs/backend.md; maintainer scripts in
# deploy/debian/fleetgw-ingest/. Its schema migrations are compiled into the binary. Two packages
# so that a bike never installs PostgreSQL's client library and a backend host not the gateway.
# Runtime dependencies are computed by dpkg-shlibdeps (package dpkg-dev) from the binaries, so a
# cross-built package depends on the arm64 libraries it really links, and only fleetgw-ingest
# on libpq5.
#
# Paths: /etc and /lib/systemd/system are absolute because that is where Debian expects them
# whatever the install prefix; `DESTDIR=/tmp/root cmake --install <build>` stages everything
# under /tmp/root for inspection (`--component fleetgw-ingest` for one package's files).
set(FLEETGW_DEPLOY_DIR ${CMAKE_CURRENT_LIST_DIR})
# The backend consumer has its own package when it is built (gateway/ingest needs libpq).
if(TARGET fleetgw-ingest)
  set(FLEETGW_INGEST_PACKAGE ON)
else()
  set(FLEETGW_INGEST_PACKAGE OFF)
endif()

# Shipped 0644 like any conffile (the default holds no secret); the postinst makes it
# root:fleetgw 0640 before a technician adds broker credentials.
install(FILES ${PROJECT_SOURCE_DIR}/config/fleetgw.toml DESTINATION /etc/fleetgw COMPONENT fleetgw)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw.service DESTINATION /lib/systemd/system
        COMPONENT fleetgw)
install(PROGRAMS ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw-can-setup
        DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/fleetgw COMPONENT fleetgw)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/80-can.network
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples COMPONENT fleetgw)
install(FILES ${PROJECT_SOURCE_DIR}/docs/deployment.md DESTINATION ${CMAKE_INSTALL_DOCDIR}
        COMPONENT fleetgw)

# Debian policy: the copyright file and the changelog (gzip -9n: reproducible) in the doc dir;
# both packages come from the one source, so they share both.
install(FILES ${FLEETGW_DEPLOY_DIR}/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR}
        COMPONENT fleetgw)
set(FLEETGW_CHANGELOG_GZ ${CMAKE_BINARY_DIR}/deploy/changelog.Debian.gz)
add_custom_command(
  OUTPUT ${FLEETGW_CHANGELOG_GZ}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/deploy
  COMMAND gzip -9nc ${FLEETGW_DEPLOY_DIR}/debian/changelog > ${FLEETGW_CHANGELOG_GZ}
  DEPENDS ${FLEETGW_DEPLOY_DIR}/debian/changelog
  VERBATIM)
add_custom_target(fleetgw_changelog ALL DEPENDS ${FLEETGW_CHANGELOG_GZ})
install(FILES ${FLEETGW_CHANGELOG_GZ} DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT fleetgw)

# Manual pages, generated from the CLI definitions by help2man running the built binaries (so
# not in a cross build, whose binaries do not run here). The script takes the list of
# subcommands from `fleetgw --help`, so which pages exist is known only at build time: the
# directory is installed, fleetgw.1.gz (always written) stands for all of them.
if(NOT CMAKE_CROSSCOMPILING AND TARGET fleetgw-watch)
  find_program(FLEETGW_HELP2MAN help2man)
  if(FLEETGW_HELP2MAN)
    set(man_dir ${CMAKE_BINARY_DIR}/deploy/man)
    set(man_outputs ${man_dir}/fleetgw.1.gz)
    set(man_ingest)
    if(FLEETGW_INGEST_PACKAGE)
      list(APPEND man_outputs ${man_dir}/fleetgw-ingest.1.gz)
      set(man_ingest $<TARGET_FILE:fleetgw-ingest>)
    endif()
    add_custom_command(
      OUTPUT ${man_outputs}
      COMMAND ${FLEETGW_DEPLOY_DIR}/man/make-man-pages.sh $<TARGET_FILE:fleetgw>
              $<TARGET_FILE:fleetgw-watch> ${PROJECT_VERSION} ${man_dir} ${man_ingest}
      DEPENDS fleetgw fleetgw-watch ${man_ingest} ${FLEETGW_DEPLOY_DIR}/man/make-man-pages.sh
      VERBATIM)
    add_custom_target(fleetgw_man_pages ALL DEPENDS ${man_outputs})
    install(DIRECTORY ${man_dir}/ DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT fleetgw
            FILES_MATCHING PATTERN "*.1.gz" PATTERN "fleetgw-ingest.1.gz" EXCLUDE
            PATTERN "fleetgw-fleet-sim.1.gz" EXCLUDE
            PATTERN "fleetgw-serve.1.gz" EXCLUDE)  # in fleetgw-ingest, with the program
  else()
    message(STATUS "help2man not found: the packages will have no manual pages")
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
          DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions COMPONENT fleetgw)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME fleetgw)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "fleetgw maintainers <fleetgw@example.org>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # the build keeps debug info; the flash of an IoT node does not
# One package per component, each named <package>_<version>-<release>_<arch>.deb.
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL fleetgw)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)

set(CPACK_DEBIAN_FLEETGW_PACKAGE_NAME fleetgw)
set(CPACK_DEBIAN_FLEETGW_PACKAGE_SECTION net)
# First line: the summary; the others stay under 80 characters (lintian). (No
# CPACK_PACKAGE_DESCRIPTION_SUMMARY: CPack would put that one on top of both packages.)
set(CPACK_DEBIAN_FLEETGW_DESCRIPTION
    "MOTINOVA e-bike fleet telemetry gateway\n\
Runs on the e-bike's IoT node: decodes the MOTINOVA CAN bus, records rides,\n\
faults, pack statistics, telemetry and lock events in SQLite, and syncs them to\n\
an MQTT broker.")
# adduser: the postinst creates the system user. The recommended and suggested packages serve
# the optional CAN helper, the GNSS receiver ([gnss], through gpsd) and the technician.
# libgps: loaded at run time by the gpsd client (gateway/gnss/gpsd_client.cc), so
# dpkg-shlibdeps does not see it; its package is named after the soname the build recorded
# (libgps.so.28 -> libgps28, Debian's library package naming).
string(REGEX REPLACE "^libgps\\.so\\.([0-9]+)$" "libgps\\1" FLEETGW_LIBGPS_PACKAGE
                     "${FLEETGW_LIBGPS_SONAME}")
set(CPACK_DEBIAN_FLEETGW_PACKAGE_DEPENDS "adduser, ${FLEETGW_LIBGPS_PACKAGE}")
set(CPACK_DEBIAN_FLEETGW_PACKAGE_RECOMMENDS "iproute2, gpsd")
set(CPACK_DEBIAN_FLEETGW_PACKAGE_SUGGESTS "can-utils, mosquitto-clients")
set(CPACK_DEBIAN_FLEETGW_PACKAGE_CONTROL_EXTRA
    ${FLEETGW_DEPLOY_DIR}/debian/conffiles ${FLEETGW_DEPLOY_DIR}/debian/postinst
    ${FLEETGW_DEPLOY_DIR}/debian/prerm ${FLEETGW_DEPLOY_DIR}/debian/postrm)

if(FLEETGW_INGEST_PACKAGE)
  include(${FLEETGW_DEPLOY_DIR}/packaging-ingest.cmake)
endif()

# A cross build packages for the target: dpkg --print-architecture would name the build host.
if(CMAKE_CROSSCOMPILING)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE armhf)
  endif()
endif()

include(CPack)
