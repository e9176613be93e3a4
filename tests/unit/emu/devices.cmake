# The device emulators (host/emu/devices.cmake) against the real device classes of zerog::rtio:
# AtiBoard ↔ NetcanoemSensor over FakeCanBus, Stim300Emulator ↔ Stim300Imu over a real pty.
zerog_add_test(emu_devices_test SOURCES emu/devices_test.cpp LIBS zerog::emu_devices zerog::rtio zerog_test_alloc)
# rtio_test (tests/unit/CMakeLists.txt) emulates its ATI board with zerog::emu::AtiBoard
# (rtio/netcanoem_sensor_test.cpp, rtio/netcanoem_board.hpp): the lead may move this into its LIBS.
target_link_libraries(rtio_test PRIVATE zerog::emu_devices)
