# adapters/common: code shared by the Application Adapters (occupancy maps).
include adapters/common/adapters.mk
$(eval $(call marie_lib,adaptcommon,adapters/common/occmap.c adapters/common/occmap_load.c))
$(eval $(call marie_test,test_occmap,tests/adapters/test_occmap.c,$(ADAPT_COMMON)))
$(eval $(call marie_bench,bench_adapters,adapters/common/bench_adapters.c adapters/localizer/mcl.cpp adapters/planner/planner.cpp,$(ADAPT_COMMON) $(B)/lib/libarbiter.a $(ADAPT_OMPL_LIBS)))
# The integration tests' bus probe (not installed).
$(eval $(call marie_link,$(B)/tests/helpers/adapt_probe,tests/adapters/adapt_probe.c,))
EXTRA_TARGETS += $(B)/tests/helpers/adapt_probe
ITESTS += tests/adapters/test_nav_sim.sh
ITESTS += tests/adapters/test_nav_subscribe.sh
$(eval $(call marie_fuzz,occmap_pgm,tests/adapters/fuzz_occmap_pgm.c adapters/common/occmap.c,))
