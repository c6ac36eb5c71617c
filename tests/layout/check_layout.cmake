# The dependency rules of docs/ARCHITECTURE.md ("Layout"), checked on the build's link graph
# (GRAPH, written by tests/layout/CMakeLists.txt) and on the #include lines of the folders whose
# rule is about code, not linking (protocol/: no I/O; storage/: no protobuf).
#   cmake -DGRAPH=<build>/tests/layout/link_graph.txt -DSOURCE_DIR=<source> -P check_layout.cmake
# EXTRA_EDGE=a>b adds one edge to the graph (the test that shows a violation is caught).
# Exit status 0 when every rule holds; otherwise one line per violation, naming the rule, the
# target or file and the forbidden dependency, and a fatal error.
cmake_minimum_required(VERSION 3.25)

# Folder rules: targets defined under the first folder may not reach (through any chain of
# links) a target defined under one of the others. "gateway/core" is every gateway/ folder but
# sim/, tools/ and cli/.
set(rules
  "backend|gateway,storage"
  "storage|gateway,backend,proto"
  "env|gateway,backend,storage,proto"
  "proto|gateway,backend,storage"
  "gateway/core|gateway/sim,gateway/tools,gateway/cli,backend"
  "gateway/sim|gateway/runtime,gateway/tools,gateway/cli,backend"
  "gateway/tools|gateway/sim,gateway/cli,backend"
  "gateway/tools/common|gateway/tools/plot,gateway/tools/store,gateway/tools/operator"
  "gateway/tools/plot|gateway/tools/store,gateway/tools/operator"
  "gateway/tools/operator|gateway/tools/store,gateway/tools/plot"
  "gateway/tools/store|gateway/tools/operator")
# Third-party targets a folder may not reach. protocol/ links nothing at all (checked below).
set(third_party_rules "storage|protobuf::")
# The one documented exception: the CLI validates `fleetgw ingest`'s options before it execs
# fleetgw-ingest, so it links their definitions (CLI11 only, no libpq).
set(allowed "fleetgw_ingest_options" "fleetgw_backend_deps")
# The record-kind table (proto/record_kinds.h, docs/data-model.md "Record kinds") is plain C++
# without protobuf, made for storage/ and backend/ to share: any folder may use it.
set(shared_everywhere "fleetgw_record_kinds")

if(NOT EXISTS "${GRAPH}")
  message(FATAL_ERROR "no link graph at ${GRAPH} (configure the tree first)")
endif()
file(STRINGS "${GRAPH}" lines REGEX "^[^#]")
set(targets "")
foreach(line ${lines})
  string(REGEX MATCH "^([^|]*)\\|([^|]*)\\|(.*)$" _ "${line}")
  set(t ${CMAKE_MATCH_1})
  list(APPEND targets ${t})
  set(folder_${t} "${CMAKE_MATCH_2}")
  string(REPLACE "," ";" links "${CMAKE_MATCH_3}")
  set(links_${t} ${links})
endforeach()
if(EXTRA_EDGE)
  string(REPLACE ">" ";" edge "${EXTRA_EDGE}")
  list(GET edge 0 from)
  list(GET edge 1 to)
  list(APPEND links_${from} ${to})
endif()

# The folder a target counts as: gateway/<area>/... (not sim, tools, cli) is gateway/core too.
function(in_folder t folder out)
  set(f "${folder_${t}}")
  set(result FALSE)
  if(folder STREQUAL "gateway/core")
    if(f MATCHES "^gateway(/|$)" AND NOT f MATCHES "^gateway/(sim|tools|cli)(/|$)")
      set(result TRUE)
    endif()
  elseif(f STREQUAL folder OR f MATCHES "^${folder}/")
    set(result TRUE)
  endif()
  set(${out} ${result} PARENT_SCOPE)
endfunction()

# Everything `t` reaches through links (breadth first, each target once).
function(reach t out)
  set(seen "")
  set(queue ${links_${t}})
  while(queue)
    list(POP_FRONT queue n)
    if(NOT n IN_LIST seen)
      list(APPEND seen ${n})
      list(APPEND queue ${links_${n}})
    endif()
  endwhile()
  set(${out} ${seen} PARENT_SCOPE)
endfunction()

set(violations "")
foreach(t ${targets})
  reach(${t} reached)
  if(folder_${t} MATCHES "^protocol(/|$)" AND reached)
    list(APPEND violations "protocol/ links nothing: ${t} links ${reached}")
  endif()
  foreach(rule ${rules})
    string(REPLACE "|" ";" parts "${rule}")
    list(GET parts 0 from)
    list(GET parts 1 forbidden)
    in_folder(${t} ${from} applies)
    if(NOT applies)
      continue()
    endif()
    string(REPLACE "," ";" forbidden "${forbidden}")
    foreach(n ${reached})
      if(n IN_LIST allowed AND folder_${t} MATCHES "^gateway/cli(/|$)")
        continue()
      endif()
      if(n IN_LIST shared_everywhere)
        continue()
      endif()
      foreach(f ${forbidden})
        in_folder(${n} ${f} hit)
        if(hit)
          list(APPEND violations
            "${from}/ may not depend on ${f}/: ${t} (${folder_${t}}) reaches ${n} (${folder_${n}})")
        endif()
      endforeach()
    endforeach()
  endforeach()
  foreach(rule ${third_party_rules})
    string(REPLACE "|" ";" parts "${rule}")
    list(GET parts 0 from)
    list(GET parts 1 prefix)
    in_folder(${t} ${from} applies)
    if(applies)
      foreach(n ${reached})
        string(FIND "${n}" "${prefix}" at)
        if(at EQUAL 0)
          list(APPEND violations "${from}/ may not depend on ${prefix}: ${t} reaches ${n}")
        endif()
      endforeach()
    endif()
  endforeach()
endforeach()

# The include lines. protocol/: no I/O (no stream, file, thread, socket or OS header; project
# headers only its own). storage/: no protobuf and nothing of gateway/, backend/ or proto/.
# backend/: nothing of gateway/ or storage/. The gateway layers as in the link rules.
set(include_rules
  "protocol|<(fstream|iostream|filesystem|thread|mutex|future|condition_variable|asio|unistd\\.h|fcntl\\.h|sys/|linux/|net|sqlite3)|\"[^\"]*/|no I/O, no other library"
  "storage|\\.pb\\.h|google/protobuf|\"(gateway|backend|proto)/|no protobuf, nothing of gateway/ backend/ proto/"
  "backend|\"(gateway|storage)/|nothing of gateway/ or storage/"
  "gateway/core|\"gateway/(sim|tools|cli)/|nothing of gateway/sim, tools, cli"
  "gateway/sim|\"gateway/(runtime|tools|cli)/|nothing of gateway/runtime, tools, cli"
  "gateway/tools|\"gateway/(sim|cli)/|nothing of gateway/sim or cli")
foreach(rule ${include_rules})
  string(REGEX MATCH "^([^|]*)\\|(.*)\\|([^|]*)$" _ "${rule}")
  set(folder ${CMAKE_MATCH_1})
  set(pattern "${CMAKE_MATCH_2}")
  set(what "${CMAKE_MATCH_3}")
  if(folder STREQUAL "gateway/core")
    file(GLOB_RECURSE files "${SOURCE_DIR}/gateway/*.h" "${SOURCE_DIR}/gateway/*.cc")
    list(FILTER files EXCLUDE REGEX "/gateway/(sim|tools|cli)/")
  else()
    file(GLOB_RECURSE files "${SOURCE_DIR}/${folder}/*.h" "${SOURCE_DIR}/${folder}/*.cc")
  endif()
  foreach(file ${files})
    file(STRINGS "${file}" includes REGEX "^[ \t]*#[ \t]*include")
    foreach(inc ${includes})
      # protocol/'s own headers: "motinova/..." and the neighbours of a source file.
      if(folder STREQUAL "protocol" AND inc MATCHES "\"motinova/")
        continue()
      endif()
      if(inc MATCHES "\"proto/record_kinds\\.h\"")  # shared_everywhere, above
        continue()
      endif()
      if(inc MATCHES "${pattern}")
        file(RELATIVE_PATH rel "${SOURCE_DIR}" "${file}")
        list(APPEND violations "${folder}/: ${what}: ${rel}: ${inc}")
      endif()
    endforeach()
  endforeach()
endforeach()

if(violations)
  foreach(v ${violations})
    message("violates: ${v}")
  endforeach()
  list(LENGTH violations n)
  message(FATAL_ERROR "${n} dependency rule violation(s) (docs/ARCHITECTURE.md, Layout)")
endif()
list(LENGTH targets n)
message("dependency rules hold for ${n} targets")
