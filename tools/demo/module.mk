# tools/demo: marie-demo, the driver behind make demo and the robot application's tests.
$(eval $(call marie_program,marie-demo,tools/demo/demo.cpp tools/demo/demo_report.cpp tools/demo/chaos.c,$(ADAPT_COMMON) $(shell pkg-config --libs opencv4 2>/dev/null)))
$(B)/obj/tools/demo/demo.o $(B)/obj/tools/demo/demo_report.o: CXXFLAGS += $(shell pkg-config --cflags opencv4 2>/dev/null)
# What the installed marie-demo runs from (it changes to <bin>/../share/marie when the system
# file is not in its working directory): the system files, the worlds their paths name, the
# simulator's phrases.
INSTALL_EXTRA += install -d $(DESTDIR)$(PREFIX)/share/marie/config $(DESTDIR)$(PREFIX)/share/marie/sim/worlds \
    $(DESTDIR)$(PREFIX)/share/marie/sounds && install -m 644 config/*.yaml $(DESTDIR)$(PREFIX)/share/marie/config/ && \
    install -m 644 sim/worlds/*.yaml sim/worlds/*.pgm $(DESTDIR)$(PREFIX)/share/marie/sim/worlds/ && \
    { ! ls $(B)/share/sounds/*.wav >/dev/null 2>&1 || install -m 644 $(B)/share/sounds/*.wav $(DESTDIR)$(PREFIX)/share/marie/sounds/; };
ITESTS += tests/tools/test_install.sh
$(eval $(call marie_test,test_demo_chaos,tests/tools/test_demo_chaos.c tools/demo/chaos.c,))
