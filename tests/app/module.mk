# tests/app: the robot application's integration tests (marie-demo; the spoken mission under the managers).
$(eval $(call marie_link,$(B)/tests/replay_check,tests/app/replay_check.c,))
EXTRA_TARGETS += $(B)/tests/replay_check
ITESTS += tests/app/test_robot_app.sh
$(eval $(call marie_link,$(B)/tests/estop_check,tests/app/estop_check.c,))
EXTRA_TARGETS += $(B)/tests/estop_check
$(eval $(call marie_link,$(B)/tests/spoken_probe,tests/app/spoken_probe.c,))
EXTRA_TARGETS += $(B)/tests/spoken_probe
ITESTS += tests/app/test_spoken_mission.sh
# test_spoken_mission runs the audio chain on the phrases the build speaks.
$(B)/tests/spoken_probe: | $(B)/bin/marie-ssl $(B)/bin/marie-asr $(B)/bin/marie-dialogue $(B)/bin/marie-tts \
    $(B)/bin/marie-audio $(B)/share/sounds/phrases.stamp
# Out of make test until mended: the live explore run misses its pose check (RMS < 0.10 m) in
# about 1 run of 8 (a drift along the office's long corridor; the mapper before the Radish work
# misses it on the same recorded run). docs/mapping.md, "Real robots' logs".
SLOW_TESTS += tests/app/test_explore_app.sh
