# adapters/mapper: marie-mapper (scan matching, pose graph with Ceres, occupancy grid on the bus).
include adapters/common/adapters.mk
MAPPER_LIBS := $(B)/lib/libmapper.a $(ADAPT_COMMON) -lceres -lglog
$(B)/obj/adapters/mapper/%.o: CPPFLAGS += $(ADAPT_EIGEN_CFLAGS)
$(eval $(call marie_lib,mapper,adapters/mapper/slam.cpp adapters/mapper/scangrid.cpp adapters/mapper/posegraph.cpp))
$(eval $(call marie_program,marie-mapper,adapters/mapper/mapper_main.c,$(MAPPER_LIBS)))
$(eval $(call marie_test,test_slam,tests/mapper/test_slam.c,$(MAPPER_LIBS)))
$(eval $(call marie_bench,bench_mapper,bench/bench_mapper.cpp,$(MAPPER_LIBS)))
# The integration test's pilot, and a recorded run through the mapper's library (not installed).
$(eval $(call marie_link,$(B)/tests/helpers/route_driver,tests/mapper/route_driver.c,))
$(eval $(call marie_link,$(B)/tests/helpers/mapper_replay,tests/mapper/mapper_replay.c tests/mapper/replay.c,$(MAPPER_LIBS)))
$(eval $(call marie_link,$(B)/tests/helpers/map_updates_check,tests/mapper/map_updates_check.c,$(MAP_LIB)))
EXTRA_TARGETS += $(B)/tests/helpers/route_driver $(B)/tests/helpers/mapper_replay $(B)/tests/helpers/map_updates_check
ITESTS += tests/mapper/test_mapper_replay.sh
ITESTS += tests/mapper/test_map_updates.sh
SLOW_TESTS += tests/mapper/test_mapper_sim.sh
# The simulated robot mapping the office along a route (~2 min) and by itself (3-4 min):
# make test-slow runs them (make test stays within its 20 minutes; docs/mapping.md).
SLOW_TESTS += tests/mapper/test_explore_sim.sh
# The mapper on the nine real robots' logs of tests/data/radish (about 35 s).
$(eval $(call marie_bench,bench_mapper_radish,bench/bench_mapper_radish.cpp tests/mapper/replay.c tools/log/carmen.c,$(MAPPER_LIBS) $(MAP_LIB) -lz))
ITESTS += tests/mapper/test_radish.sh
