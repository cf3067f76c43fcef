# hw/lms200: SICK LMS200 laser: telegram codec, serial I/O, driver, emulator and components.
LMS200_SRCS := hw/lms200/lms200.c hw/lms200/serial.c hw/lms200/driver.c hw/lms200/vlms200.c
LMS200_LIB := $(B)/lib/libmarie_lms200.a
$(eval $(call marie_lib,marie_lms200,$(LMS200_SRCS)))

$(eval $(call marie_test,test_lms200,tests/hw/test_lms200.c,$(LMS200_LIB)))
$(eval $(call marie_test,test_lms200_driver,tests/hw/test_lms200_driver.c,$(LMS200_LIB) -lutil))

$(eval $(call marie_program,marie-lms200,hw/lms200/lms200_main.c,$(LMS200_LIB) -lutil))
$(eval $(call marie_program,marie-vlms200,hw/lms200/vlms200_main.c,$(LMS200_LIB) -lutil))

$(eval $(call marie_test,test_lms200_component,tests/hw/test_lms200_component.c tests/proc.c))
$(B)/tests/test_lms200_component: $(B)/bin/marie-lms200 $(B)/bin/marie-vlms200
ITESTS += tests/hw/test_lms200_ps.sh

# libFuzzer builds take sources only, so the codec is listed as a source here.
$(eval $(call marie_fuzz,lms200,tests/hw/fuzz_lms200.c hw/lms200/lms200.c))

$(eval $(call marie_bench,bench_lms200,bench/bench_lms200.c tests/proc.c,$(LMS200_LIB)))
$(B)/bench/bench_lms200: $(B)/bin/marie-lms200 $(B)/bin/marie-vlms200
