# tools/face: marie-face, the touch page for people near the robot (docs/face.md), on
# the viewer's server code (tools/webcommon); its test.
$(eval $(call marie_program,marie-face,tools/face/face_main.c tools/webcommon/webserve.c tools/webcommon/webproto.c tools/webcommon/vjson.c tools/webcommon/webpin.c tools/webcommon/pinguard.c,$(PROTO_LIB) -lnettle))
INSTALL_EXTRA += install -d $(DESTDIR)$(PREFIX)/share/marie/face && install -m 644 tools/face/www/* $(DESTDIR)$(PREFIX)/share/marie/face/;
$(eval $(call marie_link,$(B)/tests/helpers/face_probe,tests/face/face_probe.c,))
EXTRA_TARGETS += $(B)/tests/helpers/face_probe
ITESTS += tests/face/test_face.sh tests/face/test_face_pin.sh
$(eval $(call marie_bench,bench_face,bench/bench_face.c,-lcivetweb))
$(B)/bench/bench_face: | $(B)/bin/marie-face $(B)/bin/marie-mission $(B)/bin/marie-sim $(B)/bin/marie-odometry \
    $(B)/bin/marie-localizer $(B)/bin/marie-planner $(B)/bin/marie-ca $(B)/bin/marie-behaviours
ITESTS += tests/face/test_face_sim.sh
