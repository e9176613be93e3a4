# zerog::emu_devices — device emulators for the hardware-in-the-loop tests and zerog-emu: an ATI
# NETCANOEM board on a CAN bus (AtiBoard) and a STIM300 writing into a pty (Stim300Emulator).
# Protocol encoders from zerog::proto; the CAN bus interface from zerog::rtio, the in-memory bus
# the board answers on (FakeCanBus, AtiBoardResponder) from zerog::rtio_fakes.
add_library(zerog_emu_devices ${CMAKE_CURRENT_LIST_DIR}/src/ati_board.cpp
                              ${CMAKE_CURRENT_LIST_DIR}/src/stim300_emulator.cpp)
add_library(zerog::emu_devices ALIAS zerog_emu_devices)
target_include_directories(zerog_emu_devices PUBLIC $<BUILD_INTERFACE:${CMAKE_CURRENT_LIST_DIR}/include>)
target_link_libraries(zerog_emu_devices PUBLIC zerog::rtio zerog::rtio_fakes zerog::proto Eigen3::Eigen)
target_compile_features(zerog_emu_devices PUBLIC cxx_std_20)
zerog_warnings(zerog_emu_devices)
