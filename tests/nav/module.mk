# tests/nav: navigation beyond the office world (robot size, livelock, kidnapping, evaluation).
ITESTS += tests/nav/test_small_robot.sh
ITESTS += tests/nav/test_livelock.sh
# marie-eval's short run (the long one is make bench's bench_eval).
ITESTS += tests/nav/test_eval.sh
$(eval $(call marie_test,test_kidnap,tests/nav/test_kidnap.c tests/proc.c,))
$(B)/tests/test_kidnap: | $(B)/bin/marie-sim $(B)/bin/marie-odometry $(B)/bin/marie-localizer
