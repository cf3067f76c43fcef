# tests/nav: navigation beyond the office world (robot size, livelock, kidnapping, evaluation).
ITESTS += tests/nav/test_small_robot.sh
