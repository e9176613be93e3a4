# The device emulators (host/emu/devices.cmake) against the real device classes of zerog::rtio:
# AtiBoard ↔ NetcanoemSensor over FakeCanBus, Stim300Emulator ↔ Stim300Imu over a real pty.
zerog_add_test(emu_devices_test SOURCES emu/devices_test.cpp LIBS zerog::emu_devices zerog::rtio zerog::rtio_fakes zerog_test_alloc)
