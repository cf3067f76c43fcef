# adapters/common: build settings, the benchmark and the bus probe shared by the Application Adapters.
include adapters/common/adapters.mk
$(eval $(call marie_bench,bench_adapters,adapters/common/bench_adapters.c adapters/localizer/mcl.cpp adapters/planner/planner.cpp,$(ADAPT_COMMON) $(B)/lib/libarbiter.a $(ADAPT_OMPL_LIBS)))
# The integration tests' bus probe (not installed).
$(eval $(call marie_link,$(B)/tests/helpers/adapt_probe,tests/adapters/adapt_probe.c,))
EXTRA_TARGETS += $(B)/tests/helpers/adapt_probe
ITESTS += tests/adapters/test_nav_sim.sh
ITESTS += tests/adapters/test_nav_subscribe.sh
