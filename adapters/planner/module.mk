# adapters/planner: marie-planner (A* or OMPL on the map inflated by its clearance, map/clearance.h).
include adapters/common/adapters.mk
$(B)/obj/adapters/planner/%.o: CPPFLAGS += $(ADAPT_OMPL_CFLAGS)
$(eval $(call marie_program,marie-planner,adapters/planner/planner_main.c adapters/planner/planner.cpp,$(ADAPT_COMMON) $(ADAPT_OMPL_LIBS)))
$(eval $(call marie_test,test_planner,tests/adapters/test_planner.c adapters/planner/planner.cpp,$(ADAPT_COMMON) $(ADAPT_OMPL_LIBS)))
$(eval $(call marie_test,test_planner_scan_time,tests/adapters/test_planner_scan_time.c tests/proc.c,$(ADAPT_COMMON)))
$(B)/tests/test_planner_scan_time: | $(B)/bin/marie-planner
$(eval $(call marie_test,test_planner_layer,tests/adapters/test_planner_layer.c tests/proc.c,$(ADAPT_COMMON)))
$(B)/tests/test_planner_layer: | $(B)/bin/marie-planner
