# tests/nav: navigation beyond the office world (robot size, livelock, kidnapping, evaluation).
ITESTS += tests/nav/test_small_robot.sh
ITESTS += tests/nav/test_livelock.sh
$(eval $(call marie_test,test_kidnap,tests/nav/test_kidnap.c tests/proc.c,))
$(B)/tests/test_kidnap: | $(B)/bin/marie-sim $(B)/bin/marie-odometry $(B)/bin/marie-localizer
