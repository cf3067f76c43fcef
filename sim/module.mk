# sim: marie-sim, the ODE simulator (channel and device modes), and its worlds.
ODE_LIBS := $(shell pkg-config --libs ode 2>/dev/null)
SIM_LIB := $(B)/lib/libmariesim.a $(MAP_LIB)

$(eval $(call marie_lib,mariesim,sim/walls.c sim/world.c))

$(eval $(call marie_test,test_sim_world,tests/sim/test_sim_world.c,$(SIM_LIB) $(ODE_LIBS)))

# Device mode drives the hw/ emulators: virtual CiA 402 drives and gyro, virtual LMS200.
SIM_DEVICE_LIBS := $(B)/lib/libmarie_vdevices.a $(B)/lib/libmarie_drives.a $(B)/lib/libmarie_gyro.a \
    $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a $(B)/lib/libmarie_lms200.a -lutil
$(eval $(call marie_program,marie-sim,sim/sim_main.c sim/devices.c,$(SIM_LIB) $(SIM_DEVICE_LIBS) $(ODE_LIBS)))

$(eval $(call marie_bench,bench_sim,sim/bench_sim.c,$(SIM_LIB) $(ODE_LIBS)))
$(B)/bench/bench_sim: | $(B)/bin/marie-sim

$(eval $(call marie_test,test_sim_channels,tests/sim/test_sim_channels.c tests/proc.c,))
# The device-mode case runs the real drivers against the simulator.
$(B)/tests/test_sim_channels: | $(B)/bin/marie-sim $(B)/bin/marie-drives $(B)/bin/marie-gyro $(B)/bin/marie-lms200


# Device mode as fast as the computer allows, with the real drivers on the sim clock.
$(eval $(call marie_test,test_sim_fast_devices,tests/sim/test_sim_fast_devices.c tests/proc.c,))
$(B)/tests/test_sim_fast_devices: | $(B)/bin/marie-sim $(B)/bin/marie-drives $(B)/bin/marie-gyro $(B)/bin/marie-lms200
