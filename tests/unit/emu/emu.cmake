# zerog::emu (helper emurobot): the robot controller emulator (with an end-to-end run of the robot
# loop against a UDP responder), the payload physics with pushes, the scenario file; and the
# emulated rig against zerog-rt's cycle (spin_contact_test: contact stays zero while it turns).
zerog_add_test(emu_test SOURCES emu/robot_test.cpp emu/physics_test.cpp emu/scenario_test.cpp
               emu/spin_contact_test.cpp
               LIBS zerog::emu zerog::model zerog::loop zerog_test_rsi_step)

# The zerog-emu program with its F/T board on a local CAN bus socket (--can-local).
zerog_add_test(emu_can_local_test SOURCES emu/can_local_test.cpp LIBS zerog::rtio)
target_compile_definitions(emu_can_local_test PRIVATE ZEROG_EMU_EXE="$<TARGET_FILE:zerog-emu>")
add_dependencies(emu_can_local_test zerog-emu)
