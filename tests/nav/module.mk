# tests/nav: navigation beyond the office world (robot size, livelock, kidnapping, unmapped
# obstacles, coarse maps, evaluation). Whole-robot runs of 40-90 s each are make test-slow's
# (make test stays within its 20 minutes); the defects' tests run in make test.
SLOW_TESTS += tests/nav/test_small_robot.sh
SLOW_TESTS += tests/nav/test_livelock.sh
# marie-eval's short run (the long one is make bench-full's bench_eval).
SLOW_TESTS += tests/nav/test_eval.sh
NAV_STACK := $(B)/bin/marie-sim $(B)/bin/marie-odometry $(B)/bin/marie-localizer $(B)/bin/marie-planner \
    $(B)/bin/marie-behaviours
$(eval $(call marie_test,test_kidnap,tests/nav/test_kidnap.c tests/nav/navrig.c tests/proc.c,$(MAP_LIB)))
$(B)/tests/test_kidnap: | $(NAV_STACK)
$(eval $(call marie_test,test_relocalize,tests/nav/test_relocalize.c tests/nav/navrig.c tests/proc.c,$(MAP_LIB)))
$(B)/tests/test_relocalize: | $(NAV_STACK)
$(eval $(call marie_test,test_unmapped,tests/nav/test_unmapped.c tests/nav/navrig.c tests/proc.c,$(MAP_LIB)))
$(B)/tests/test_unmapped: | $(NAV_STACK)
$(eval $(call marie_test,test_bad_start,tests/nav/test_bad_start.c tests/proc.c,))
$(B)/tests/test_bad_start: | $(B)/bin/marie-localizer $(B)/bin/marie-planner
ITESTS += tests/nav/test_eval_map.sh
SLOW_TESTS += tests/nav/test_coarse_map.sh
