# tools: lcm-spy launcher and log record/replay wrappers (scripts copied to $(B)/bin), and the
# helper the tools test uses to publish and hear every marie type.
TOOLS_SCRIPTS := marie-spy marie-record marie-play
$(addprefix $(B)/bin/,$(TOOLS_SCRIPTS)): $(B)/bin/%: tools/%
	@mkdir -p $(@D)
	cp $< $@ && chmod 755 $@
EXTRA_TARGETS += $(addprefix $(B)/bin/,$(TOOLS_SCRIPTS))
INSTALL_EXTRA += install -m 755 $(addprefix $(B)/bin/,$(TOOLS_SCRIPTS)) $(DESTDIR)$(PREFIX)/bin/ && install -d $(DESTDIR)$(PREFIX)/share/marie && install -m 644 $(LCM_JAR) $(DESTDIR)$(PREFIX)/share/marie/;

$(eval $(call marie_link,$(B)/tests/bin/xb-samples,tests/tools/xb_samples.c tests/xml_bridge/xb_canon.c $(XB_STRUCTDUMP),$(XB_LIB) -lexpat))
EXTRA_TARGETS += $(B)/tests/bin/xb-samples
# marie-record on shm/local channels: a component publishing through the rings
$(eval $(call marie_test,test_record_shm,tests/tools/test_record_shm.c tests/proc.c))
ITESTS += tests/tools/test_marie_tools.sh tests/tools/test_run_tests.sh tests/tools/test_record_full_disk.sh
