# sim: marie-sim, the ODE simulator (channel mode), with its map loader and worlds.
ODE_LIBS := $(shell pkg-config --libs ode)
SIM_LIB := $(B)/lib/libmariesim.a

$(eval $(call marie_lib,mariesim,sim/pgm.c sim/map.c sim/world.c))

$(eval $(call marie_test,test_sim_world,tests/sim/test_sim_world.c,$(SIM_LIB) $(ODE_LIBS)))

$(eval $(call marie_program,marie-sim,sim/sim_main.c,$(SIM_LIB) $(ODE_LIBS)))

$(eval $(call marie_bench,bench_sim,sim/bench_sim.c,$(SIM_LIB) $(ODE_LIBS)))
$(B)/bench/bench_sim: | $(B)/bin/marie-sim

$(eval $(call marie_test,test_sim_channels,tests/sim/test_sim_channels.c,))
$(B)/tests/test_sim_channels: | $(B)/bin/marie-sim
