# zerog::modbus: the pure request decisions, the register map against proto/modbus.md, and the
# server over real TCP on 127.0.0.1, with libmodbus's client and with mbpoll (an independent
# client, Debian's package) against a real loop::Cycle stepped by a test thread.
find_program(ZEROG_MBPOLL mbpoll)
zerog_add_test(modbus_test SOURCES modbus/request_test.cpp modbus/doc_test.cpp
                                   modbus/server_test.cpp
               LIBS zerog::modbus zerog_test_rsi_step PkgConfig::MODBUS)
target_include_directories(modbus_test PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/loop
                                               ${CMAKE_CURRENT_SOURCE_DIR}/modbus)
target_compile_definitions(modbus_test PRIVATE ZEROG_MBPOLL="${ZEROG_MBPOLL}")
