# How fleetgw links its third-party libraries. Included once from the top-level CMakeLists.txt,
# before any target is defined, so every area (storage, gateway, tests) agrees.
#
# FLEETGW_STATIC_DEPS (default ON) trades a little build time for resident memory on the IoT
# node: every shared library is mapped whole, relocated at start-up and faulted in 64 KiB at a
# time, so a library of which fleetgw uses a small part costs far more RAM than that part.
#   * protobuf and SQLite are linked from their static archives: only the objects fleetgw
#     references end up in the binary;
#   * spdlog (its implementation compiled once, third_party/spdlog_compiled.cc), fmt and toml++
#     are compiled into fleetgw from their headers;
#   * sections are garbage-collected at link time and unused shared libraries are not recorded
#     as needed.
# Paho and OpenSSL stay shared (Debian ships no static Paho C++). Measured effect:
# docs/performance.md, "Resident memory".
#
# Defines fleetgw::spdlog and fleetgw::toml, the targets the areas link instead of the
# packages' own.

find_package(spdlog REQUIRED)
find_package(tomlplusplus REQUIRED)
find_package(Threads REQUIRED)

add_library(fleetgw_spdlog INTERFACE)
add_library(fleetgw::spdlog ALIAS fleetgw_spdlog)
add_library(fleetgw_toml INTERFACE)
add_library(fleetgw::toml ALIAS fleetgw_toml)

if(FLEETGW_STATIC_DEPS)
  find_library(FLEETGW_PROTOBUF_STATIC NAMES libprotobuf.a)
  find_library(FLEETGW_SQLITE3_STATIC NAMES libsqlite3.a)
  if(FLEETGW_PROTOBUF_STATIC AND FLEETGW_SQLITE3_STATIC)
    # Normal variables, read by FindProtobuf and FindSQLite3; they also win over a shared
    # library that an older cache of the build directory recorded.
    set(Protobuf_LIBRARY ${FLEETGW_PROTOBUF_STATIC})
    set(Protobuf_LIBRARY_RELEASE ${FLEETGW_PROTOBUF_STATIC})
    set(SQLite3_LIBRARY ${FLEETGW_SQLITE3_STATIC})
  else()
    message(WARNING "FLEETGW_STATIC_DEPS: libprotobuf.a or libsqlite3.a not found; linking them shared")
  endif()
  # spdlog's own implementation is compiled once (third_party/spdlog_compiled.cc) instead of
  # in every file that logs; fmt stays header-only (Debian ships it shared only).
  get_target_property(_spdlog_inc spdlog::spdlog INTERFACE_INCLUDE_DIRECTORIES)
  target_include_directories(fleetgw_spdlog SYSTEM INTERFACE ${_spdlog_inc})
  target_compile_definitions(fleetgw_spdlog
    INTERFACE SPDLOG_COMPILED_LIB SPDLOG_FMT_EXTERNAL FMT_HEADER_ONLY=1)
  target_link_libraries(fleetgw_spdlog INTERFACE Threads::Threads)
  set(_fleetgw_spdlog_compiled ON)
  get_target_property(_toml_inc tomlplusplus::tomlplusplus INTERFACE_INCLUDE_DIRECTORIES)
  target_include_directories(fleetgw_toml SYSTEM INTERFACE ${_toml_inc})
  target_compile_definitions(fleetgw_toml INTERFACE TOML_HEADER_ONLY=1)
  if(NOT FLEETGW_SANITIZE AND NOT FLEETGW_FUZZ)
    add_compile_options(-ffunction-sections -fdata-sections)
    add_link_options(LINKER:--gc-sections LINKER:--as-needed)
  endif()
else()
  target_link_libraries(fleetgw_spdlog INTERFACE spdlog::spdlog)
  target_link_libraries(fleetgw_toml INTERFACE tomlplusplus::tomlplusplus)
endif()

# After the compile options above, so the one copy of spdlog gets the same section flags.
if(_fleetgw_spdlog_compiled)
  add_library(fleetgw_spdlog_compiled STATIC ${PROJECT_SOURCE_DIR}/third_party/spdlog_compiled.cc)
  target_include_directories(fleetgw_spdlog_compiled SYSTEM PRIVATE ${_spdlog_inc})
  target_compile_definitions(fleetgw_spdlog_compiled
    PRIVATE SPDLOG_COMPILED_LIB SPDLOG_FMT_EXTERNAL FMT_HEADER_ONLY=1)
  target_link_libraries(fleetgw_spdlog_compiled PRIVATE Threads::Threads)
  target_link_libraries(fleetgw_spdlog INTERFACE fleetgw_spdlog_compiled)
endif()
