# tests/nav: navigation beyond the office world (robot size, livelock, kidnapping, evaluation).
# Whole-robot runs of 40-90 s each: make test-slow (make test stays within its 20 minutes).
SLOW_TESTS += tests/nav/test_small_robot.sh
SLOW_TESTS += tests/nav/test_livelock.sh
# marie-eval's short run (the long one is make bench's bench_eval).
SLOW_TESTS += tests/nav/test_eval.sh
$(eval $(call marie_test,test_kidnap,tests/nav/test_kidnap.c tests/proc.c,))
$(B)/tests/test_kidnap: | $(B)/bin/marie-sim $(B)/bin/marie-odometry $(B)/bin/marie-localizer
