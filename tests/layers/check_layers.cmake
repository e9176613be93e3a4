# cmake -DGRAPH=<build>/tests/layers/layers_graph.cmake [-DINJECT=from>to;…] -P check_layers.cmake
#
# Reads the project's link graph (written at configuration by tests/layers/CMakeLists.txt) and
# fails, naming each path, if
#   - a target defined under firmware/ links a target defined under host/, directly or through
#     other targets (among them zerog::io, zerog::sim, zerog::ident, zerog::learn, zerog::emu);
#   - zerog::loop links zerog::rtio, directly or through other targets.
# INJECT adds links (from>to, real target names) before the check: the mutants use it to show
# that a bad link is caught. Prints "layers: ok" when nothing is wrong.
cmake_minimum_required(VERSION 3.25)
if(NOT GRAPH OR NOT EXISTS "${GRAPH}")
  message(FATAL_ERROR "layers: no link graph '${GRAPH}' (configure the project first)")
endif()
include("${GRAPH}")

foreach(link IN LISTS INJECT)
  if(NOT link MATCHES "^([^>]+)>([^>]+)$")
    message(FATAL_ERROR "layers: INJECT wants from>to, got '${link}'")
  endif()
  list(APPEND ZEROG_LINKS_${CMAKE_MATCH_1} ${CMAKE_MATCH_2})
  message(STATUS "layers: injected link ${CMAKE_MATCH_1} -> ${CMAKE_MATCH_2}")
endforeach()

# The graph must hold what the rules are about, else the check would pass vacuously.
set(host_libraries zerog_io zerog_sim zerog_ident zerog_learn zerog_emu)
foreach(t IN ITEMS zerog_loop zerog_rtio zerog_rt zerog_formats ${host_libraries})
  if(NOT t IN_LIST ZEROG_TARGETS)
    message(FATAL_ERROR "layers: target ${t} is not in the link graph ${GRAPH}")
  endif()
endforeach()
foreach(t IN LISTS host_libraries)
  if(NOT ZEROG_DIR_${t} MATCHES "^host/")
    message(FATAL_ERROR "layers: ${t} is defined in '${ZEROG_DIR_${t}}', expected under host/")
  endif()
endforeach()

# Breadth-first search from `start`; sets reached_<start> (the targets it links, transitively)
# and via_<start>_<t> (the target before t on a shortest path).
function(layers_reach start)
  set(queue ${start})
  set(seen ${start})
  while(queue)
    list(POP_FRONT queue t)
    foreach(next IN LISTS ZEROG_LINKS_${t})
      if(NOT next IN_LIST seen)
        list(APPEND seen ${next})
        list(APPEND queue ${next})
        set(via_${start}_${next} ${t} PARENT_SCOPE)
        set(via_${next} ${t})
      endif()
    endforeach()
  endwhile()
  list(REMOVE_ITEM seen ${start})
  set(reached_${start} ${seen} PARENT_SCOPE)
endfunction()

# "directly" or "through a -> b" for the shortest path start … target.
function(layers_path start target out_var)
  set(chain "")
  set(t ${via_${start}_${target}})
  while(NOT t STREQUAL start)
    list(PREPEND chain ${t})
    set(t ${via_${start}_${t}})
  endwhile()
  if(chain)
    list(JOIN chain " -> " text)
    set(${out_var} "through ${text}" PARENT_SCOPE)
  else()
    set(${out_var} "directly" PARENT_SCOPE)
  endif()
endfunction()

set(violations 0)
set(firmware_targets 0)
foreach(t IN LISTS ZEROG_TARGETS)
  if(NOT ZEROG_DIR_${t} MATCHES "^firmware(/|$)")
    continue()
  endif()
  math(EXPR firmware_targets "${firmware_targets} + 1")
  layers_reach(${t})
  foreach(r IN LISTS reached_${t})
    if(ZEROG_DIR_${r} MATCHES "^host(/|$)")
      layers_path(${t} ${r} how)
      message("layers: ${t} (${ZEROG_DIR_${t}}) links ${r} (${ZEROG_DIR_${r}}) ${how}")
      math(EXPR violations "${violations} + 1")
    endif()
  endforeach()
endforeach()

layers_reach(zerog_loop)
if(zerog_rtio IN_LIST reached_zerog_loop)
  layers_path(zerog_loop zerog_rtio how)
  message("layers: zerog_loop links zerog_rtio ${how}")
  math(EXPR violations "${violations} + 1")
endif()

if(violations GREATER 0)
  message(FATAL_ERROR "layers: ${violations} forbidden link(s): firmware/ must not link host/, "
                      "and zerog::loop must not link zerog::rtio (tests/layers)")
endif()
message("layers: ok (${firmware_targets} firmware targets, none links host/; zerog::loop does "
        "not link zerog::rtio)")
