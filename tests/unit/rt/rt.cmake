# zerog::rt: configuration, the allocation-free cycle loop, the recorder, and the runtime end to
# end on loopback UDP; config_test also runs the zerog-rt program (--check-config, start-up).
zerog_add_test(rt_test SOURCES rt/config_test.cpp rt/cycle_once_test.cpp rt/recorder_test.cpp
                               rt/runtime_test.cpp rt/realtime_test.cpp
                               rt/supervision_test.cpp
               LIBS zerog::rt zerog::rtio_fakes zerog::sim zerog::emu_devices zerog_test_alloc
                    nlohmann_json::nlohmann_json)
target_compile_definitions(rt_test PRIVATE ZEROG_RT_EXE="$<TARGET_FILE:zerog-rt>")
add_dependencies(rt_test zerog-rt)
