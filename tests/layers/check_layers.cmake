# cmake -DGRAPH=<build>/tests/layers/layers_graph.cmake [-DINJECT=from>to;…] -P check_layers.cmake
#
# Reads the project's link graph (written at configuration by tests/layers/CMakeLists.txt) and
# fails, naming each path, if
#   - a target defined under firmware/ links a target defined under host/, directly or through
#     other targets (among them zerog::io, zerog::sim, zerog::ident, zerog::learn, zerog::emu);
#   - zerog::loop links zerog::rtio, directly or through other targets;
#   - a firmware target links a target its entry in the allowed link graph (below) does not name.
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

# The allowed link graph of the firmware (issue 29, "one job per library"): each target defined
# under firmware/ and the targets it may link directly. A link not listed here, or a firmware
# target not listed at all, fails, naming it: a new arrow between the libraries is a decision
# written here, not a side effect of a target_link_libraries line. Among what is left out on
# purpose: zerog::telemetry links zerog::handover, not the device code of zerog::rtio; zerog::formats
# links the cycle's record (zerog::cycle_record), not the cycle (zerog::loop), so the host tools
# that read and write files do not link the real-time cycle; zerog::loop links no protocol
# (zerog::proto): the cycle sees SI samples, the RSI border converts; no firmware target links
# the devices' fakes (zerog::rtio_fakes: tests and emulators only).
set(allowed_zerog_status "")
set(allowed_zerog_model "")
set(allowed_zerog_samples "")
set(allowed_zerog_control "")
set(allowed_zerog_handover "")
set(allowed_zerog_proto zerog_samples zerog_model)
set(allowed_zerog_robot zerog_status)
set(allowed_zerog_infer zerog_model zerog_status)
set(allowed_zerog_cycle_record zerog_infer zerog_control zerog_samples)
set(allowed_zerog_loop zerog_cycle_record zerog_status zerog_infer zerog_control zerog_samples
                       zerog_robot)
set(allowed_zerog_rtio zerog_proto zerog_samples zerog_status zerog_handover)
set(allowed_zerog_rtio_fakes zerog_rtio zerog_proto)
set(allowed_zerog_formats zerog_robot zerog_cycle_record zerog_proto)
set(allowed_zerog_modbus zerog_loop zerog_status)
set(allowed_zerog_telemetry_idl "")
set(allowed_zerog_ros2_idl "")
set(allowed_zerog_telemetry_types zerog_telemetry_idl zerog_ros2_idl)
set(allowed_zerog_telemetry zerog_status zerog_loop zerog_control zerog_infer zerog_handover
                            zerog_proto)
set(allowed_zerog_rt zerog_status zerog_loop zerog_handover zerog_rtio zerog_infer zerog_formats
                     zerog_robot zerog_modbus zerog_telemetry)
set(allowed_zerog-rt zerog_rt)
foreach(t IN LISTS ZEROG_TARGETS)
  if(NOT ZEROG_DIR_${t} MATCHES "^firmware(/|$)")
    continue()
  endif()
  if(NOT DEFINED allowed_${t})
    message("layers: ${t} (${ZEROG_DIR_${t}}) is not in the allowed link graph "
            "(tests/layers/check_layers.cmake)")
    math(EXPR violations "${violations} + 1")
    continue()
  endif()
  foreach(next IN LISTS ZEROG_LINKS_${t})
    if(NOT next IN_LIST allowed_${t})
      message("layers: ${t} links ${next}, not an allowed edge of the firmware's link graph")
      math(EXPR violations "${violations} + 1")
    endif()
  endforeach()
endforeach()

if(violations GREATER 0)
  message(FATAL_ERROR "layers: ${violations} forbidden link(s): firmware/ must not link host/, "
                      "zerog::loop must not link zerog::rtio, and every firmware link must be "
                      "in the allowed graph (tests/layers)")
endif()
message("layers: ok (${firmware_targets} firmware targets, none links host/; zerog::loop does "
        "not link zerog::rtio; every firmware link is allowed)")
