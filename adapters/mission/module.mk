# adapters/mission: marie-mission (goal scheduling with priorities and deadlines; state in the SharedMap).
include adapters/common/adapters.mk
$(eval $(call marie_lib,mission,adapters/mission/mission.c adapters/mission/mission_signs.c adapters/mission/mission_request.c))
$(eval $(call marie_test,test_mission,tests/adapters/test_mission.c,$(B)/lib/libmission.a))
$(eval $(call marie_program,marie-mission,adapters/mission/mission_main.c,$(B)/lib/libmission.a $(B)/lib/libca.a))
$(eval $(call marie_fuzz,mission_goals,tests/adapters/fuzz_mission_goals.c adapters/mission/mission.c core/config.c core/log.c core/time.c,))
$(eval $(call marie_test,test_mission_signs,tests/adapters/test_mission_signs.c,$(B)/lib/libmission.a))
$(eval $(call marie_fuzz,mission_signs,tests/adapters/fuzz_mission_signs.c adapters/mission/mission_signs.c adapters/mission/mission.c core/config.c core/log.c core/time.c,))
$(eval $(call marie_lib,explore,adapters/mission/explore.c))
$(eval $(call marie_test,test_explore,tests/adapters/test_explore.c,$(B)/lib/libexplore.a $(B)/lib/libmapper.a $(ADAPT_COMMON) -lceres -lglog))
$(eval $(call marie_program,marie-explore,adapters/mission/explore_main.c,$(B)/lib/libexplore.a $(MAP_LIB)))
