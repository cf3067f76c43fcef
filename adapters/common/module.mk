# adapters/common: what the Application Adapters share: the pose buffer, build settings, the
# benchmark and the bus probe.
include adapters/common/adapters.mk
$(eval $(call marie_lib,adaptcommon,adapters/common/posebuf.c adapters/common/scanwait.c))
$(eval $(call marie_test,test_posebuf,tests/adapters/test_posebuf.c,$(ADAPT_COMMON)))
$(eval $(call marie_test,test_scanwait,tests/adapters/test_scanwait.c,$(ADAPT_COMMON)))
$(eval $(call marie_bench,bench_adapters,bench/bench_adapters.c adapters/localizer/mcl.cpp adapters/localizer/field.cpp adapters/localizer/reloc.cpp adapters/planner/planner.cpp,$(ADAPT_COMMON) $(B)/lib/libarbiter.a $(ADAPT_OMPL_LIBS)))
# The integration tests' bus probe (not installed).
$(eval $(call marie_link,$(B)/tests/helpers/adapt_probe,tests/adapters/adapt_probe.c,))
EXTRA_TARGETS += $(B)/tests/helpers/adapt_probe
ITESTS += tests/adapters/test_nav_sim.sh
ITESTS += tests/adapters/test_nav_subscribe.sh
