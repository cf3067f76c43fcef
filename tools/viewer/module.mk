# tools/viewer: marie-viewer-server (bus or log -> web page over WebSocket), the marie-view
# launcher, the page (served from tools/viewer/www or $(PREFIX)/share/marie/viewer), its tests.
VIEWER_LIBS := $(PROTO_LIB) $(MAP_LIB) -lnettle
$(eval $(call marie_program,marie-viewer-server,tools/viewer/viewer_main.c tools/viewer/viewer_log.c tools/webcommon/webserve.c tools/webcommon/webproto.c tools/webcommon/vjson.c tools/webcommon/webpin.c tools/webcommon/pinguard.c,$(VIEWER_LIBS)))

$(B)/bin/marie-view: tools/viewer/marie-view
	@mkdir -p $(@D)
	cp $< $@ && chmod 755 $@
EXTRA_TARGETS += $(B)/bin/marie-view
INSTALL_EXTRA += install -m 755 $(B)/bin/marie-view $(DESTDIR)$(PREFIX)/bin/ && install -d $(DESTDIR)$(PREFIX)/share/marie/viewer && install -m 644 tools/viewer/www/* $(DESTDIR)$(PREFIX)/share/marie/viewer/;

$(eval $(call marie_test,test_pinguard,tests/viewer/test_pinguard.c tools/webcommon/pinguard.c))
$(eval $(call marie_test,test_viewer_units,tests/viewer/test_viewer_units.c tools/webcommon/vjson.c))
$(eval $(call marie_fuzz,lcmlog,tests/viewer/fuzz_lcmlog.c))
$(eval $(call marie_fuzz,viewer_cmd,tests/viewer/fuzz_viewer_cmd.c tools/webcommon/vjson.c))

# Writes the synthetic demo log, or publishes the same stream live (not installed).
$(eval $(call marie_link,$(B)/tests/bin/viewer-gen,tests/viewer/viewer_gen.c,))
EXTRA_TARGETS += $(B)/tests/bin/viewer-gen
ITESTS += tests/viewer/test_viewer.sh
ITESTS += tests/viewer/test_viewer_controls.sh
ITESTS += tests/viewer/test_viewer_graph.sh

$(eval $(call marie_bench,bench_viewer,bench/bench_viewer.c,-lcivetweb))
$(B)/bench/bench_viewer: | $(B)/bin/marie-viewer-server $(B)/tests/bin/viewer-gen
ITESTS += tests/viewer/test_viewer_landmarks.sh tests/viewer/test_viewer_layout.sh
$(eval $(call marie_test,test_webserve,tests/viewer/test_webserve.c tools/webcommon/webserve.c tools/webcommon/webproto.c tools/webcommon/vjson.c,$(PROTO_LIB) -lnettle))
$(eval $(call marie_fuzz,webproto,tests/viewer/fuzz_webproto.c tools/webcommon/webproto.c,-lnettle))
ITESTS += tests/viewer/test_viewer_stall.sh
