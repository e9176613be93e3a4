# zerog::telemetry: conversion and configuration (pure), and TelemetryChannel with a real
# in-process Cyclone DDS participant on loopback (readers through Cyclone's C API).
zerog_add_test(telemetry_test SOURCES telemetry/convert_test.cpp telemetry/channel_test.cpp
               LIBS zerog::telemetry zerog::proto zerog_test_alloc)

# The independent subscriber (PyPI's cyclonedds in the project's .venv, hand-declared types)
# against zerog-telemetry-replay on loopback; values checked against the cycles.csv the replay
# writes in the recorder's format. Skipped (exit 77) without the venv unless
# ZEROG_REQUIRE_PY_DDS is ON (CI), where a missing venv fails the test.
option(ZEROG_REQUIRE_PY_DDS "Fail (not skip) the dds tests when the Python cyclonedds venv is missing" OFF)
if("$ENV{CI}" STREQUAL "true")  # in CI a missing capability is a failure, never a skip
  set(ZEROG_REQUIRE_PY_DDS ON)
endif()
set(ZEROG_PY_DDS "${PROJECT_SOURCE_DIR}/.venv/bin/python")
# One domain id per build tree (100..159; the watch test +60; unit tests use 10..99).
string(RANDOM LENGTH 2 ALPHABET 0123456789 _zerog_dds_domain)
math(EXPR _zerog_dds_domain "100 + ${_zerog_dds_domain} % 60")
set(_zerog_dds_check "import cyclonedds.domain")
set(_zerog_dds_missing "${ZEROG_PY_DDS} with the cyclonedds package is missing (scripts/install-deps.sh makes it)")
if(ZEROG_REQUIRE_PY_DDS)
  set(_zerog_dds_skip "echo \"FAIL: ${_zerog_dds_missing}\" >&2; exit 1")
else()
  set(_zerog_dds_skip "echo \"SKIP: ${_zerog_dds_missing}\" >&2; exit 77")
endif()
add_test(NAME telemetry_dds_python
         COMMAND sh -c "if ! '${ZEROG_PY_DDS}' -c '${_zerog_dds_check}' 2>/dev/null; then ${_zerog_dds_skip}; fi; exec sh '${PROJECT_SOURCE_DIR}/tests/telemetry/replay_test.sh' '$<TARGET_FILE:zerog-telemetry-replay>' '${ZEROG_PY_DDS}' '${CMAKE_CURRENT_BINARY_DIR}/telemetry_dds_python' ${_zerog_dds_domain}")
set_tests_properties(telemetry_dds_python PROPERTIES LABELS dds SKIP_RETURN_CODE 77 TIMEOUT 120
                                                      RESOURCE_LOCK dds)

# `zerog watch` against the replay publisher (C subscriber: no venv needed).
math(EXPR _zerog_watch_domain "${_zerog_dds_domain} + 60")
add_test(NAME telemetry_watch
         COMMAND sh ${PROJECT_SOURCE_DIR}/tests/telemetry/watch_test.sh $<TARGET_FILE:zerog>
                 $<TARGET_FILE:zerog-telemetry-replay> ${CMAKE_CURRENT_BINARY_DIR}/telemetry_watch
                 ${_zerog_watch_domain})
set_tests_properties(telemetry_watch PROPERTIES LABELS "dds;host_cli" TIMEOUT 60 RESOURCE_LOCK dds)

# ROS 2-side: the rt/ topics against a subscriber whose types come from rosbags' ROS 2 message
# definitions (tests/telemetry/ros2_subscriber.py), values checked against the replay's
# cycles.csv; and its mutants, each of which must fail the check naming what broke: a wrong type
# name (ROS 1's WrenchStamped: the wrench topics stay silent) and a wrong member order
# (Vector3 as y, x, z: every vector's x differs).
math(EXPR _zerog_ros2_domain "${_zerog_dds_domain} + 30")
set(_zerog_ros2_check "import cyclonedds.domain, rosbags.typesys")
foreach(variant "" "type_name;wrench: no message arrived" "member_order;wrench.force.x at cycle")
  if(variant STREQUAL "")
    set(_name telemetry_ros2_python)
    set(_args "")
  else()
    list(GET variant 0 _mutant)
    list(GET variant 1 _text)
    set(_name telemetry_ros2_mutant_${_mutant})
    set(_args " '${_mutant}' '${_text}'")
  endif()
  add_test(NAME ${_name}
           COMMAND sh -c "if ! '${ZEROG_PY_DDS}' -c '${_zerog_ros2_check}' 2>/dev/null; then ${_zerog_dds_skip}; fi; exec sh '${PROJECT_SOURCE_DIR}/tests/telemetry/replay_test.sh' '$<TARGET_FILE:zerog-telemetry-replay>' '${ZEROG_PY_DDS}' '${CMAKE_CURRENT_BINARY_DIR}/${_name}' ${_zerog_ros2_domain} ros2${_args}")
  set_tests_properties(${_name} PROPERTIES LABELS dds SKIP_RETURN_CODE 77 TIMEOUT 120
                                           RESOURCE_LOCK dds)
endforeach()
