# tools/demo: marie-demo, the driver behind make demo and the robot application's tests.
$(eval $(call marie_program,marie-demo,tools/demo/demo.cpp tools/demo/demo_report.cpp tools/demo/chaos.c,$(ADAPT_COMMON) $(shell pkg-config --libs opencv4 2>/dev/null)))
$(B)/obj/tools/demo/demo.o $(B)/obj/tools/demo/demo_report.o: CXXFLAGS += $(shell pkg-config --cflags opencv4 2>/dev/null)
$(eval $(call marie_test,test_demo_chaos,tests/tools/test_demo_chaos.c tools/demo/chaos.c,))
