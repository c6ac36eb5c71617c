# The fleetgw-ingest package (component fleetgw-ingest), included by packaging.cmake when the
# ingest is built: the reference backend consumer for a backend host, without the gateway's
# service, configuration or user (and the gateway's package without libpq).
set(ingest_docdir ${CMAKE_INSTALL_DATAROOTDIR}/doc/fleetgw-ingest)
install(TARGETS fleetgw-ingest RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        COMPONENT fleetgw-ingest)
install(FILES ${FLEETGW_DEPLOY_DIR}/systemd/fleetgw-ingest.service
        DESTINATION /lib/systemd/system COMPONENT fleetgw-ingest)
# The service's settings (conffile). Shipped 0644 without a secret; the postinst makes it
# root:fleetgw-ingest 0640 before passwords go in. Not under /etc/fleetgw: purging the gateway's
# package removes that directory.
install(FILES ${PROJECT_SOURCE_DIR}/config/fleetgw-ingest.env DESTINATION /etc/fleetgw-ingest
        RENAME ingest.env COMPONENT fleetgw-ingest)
install(FILES ${PROJECT_SOURCE_DIR}/docs/backend.md ${FLEETGW_DEPLOY_DIR}/debian/copyright
              ${FLEETGW_CHANGELOG_GZ}
        DESTINATION ${ingest_docdir} COMPONENT fleetgw-ingest)
if(TARGET fleetgw_man_pages)
  install(FILES ${CMAKE_BINARY_DIR}/deploy/man/fleetgw-ingest.1.gz
          DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT fleetgw-ingest)
  # fleetgw-fleet-sim (backend/fleet_sim installs it here): its page is `fleetgw fleet-sim`'s.
  if(TARGET fleetgw-fleet-sim)
    install(FILES ${CMAKE_BINARY_DIR}/deploy/man/fleetgw-fleet-sim.1.gz
            DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT fleetgw-ingest)
  endif()
  # fleetgw-serve and the console's files (backend/web installs them here).
  if(TARGET fleetgw-serve)
    install(FILES ${CMAKE_BINARY_DIR}/deploy/man/fleetgw-serve.1.gz
            DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT fleetgw-ingest)
  endif()
endif()

list(APPEND CPACK_COMPONENTS_ALL fleetgw-ingest)
set(CPACK_DEBIAN_FLEETGW-INGEST_PACKAGE_NAME fleetgw-ingest)
set(CPACK_DEBIAN_FLEETGW-INGEST_PACKAGE_SECTION net)
set(CPACK_DEBIAN_FLEETGW-INGEST_DESCRIPTION
    "MOTINOVA e-bike fleet telemetry: backend ingest into PostgreSQL\n\
Subscribes to the fleet's MQTT topics with an MQTT 5 shared subscription,\n\
decodes the gateways' protobuf envelopes and writes rides, faults, telemetry,\n\
pack statistics, lock events, commands and status into PostgreSQL, batched and\n\
idempotent. Runs on a backend host; the gateway itself is package fleetgw.")
# libpq5, Paho and the C++ runtime come from dpkg-shlibdeps; adduser for the postinst.
set(CPACK_DEBIAN_FLEETGW-INGEST_PACKAGE_DEPENDS "adduser, libjs-leaflet")  # libjs-leaflet: fleetgw serve
set(CPACK_DEBIAN_FLEETGW-INGEST_PACKAGE_SUGGESTS "postgresql, mosquitto")
set(CPACK_DEBIAN_FLEETGW-INGEST_PACKAGE_CONTROL_EXTRA
    ${FLEETGW_DEPLOY_DIR}/debian/fleetgw-ingest/conffiles
    ${FLEETGW_DEPLOY_DIR}/debian/fleetgw-ingest/postinst
    ${FLEETGW_DEPLOY_DIR}/debian/fleetgw-ingest/prerm
    ${FLEETGW_DEPLOY_DIR}/debian/fleetgw-ingest/postrm)
