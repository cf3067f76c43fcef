# adapters/vision: AprilTag detection, tracking and message reading (marie-vision), its tests
# and benchmark; the synthetic camera is in camera/ (libmarie_camera, also for the simulator).
VISION_CV_CFLAGS := $(shell pkg-config --cflags opencv4 2>/dev/null)
include adapters/common/adapters.mk
VISION_LIBS := $(B)/lib/libvision.a $(ADAPT_COMMON) $(CAMERA_LIBS) -lopencv_videoio
$(B)/obj/adapters/vision/%.o $(B)/obj/tests/vision/%.o: CPPFLAGS += $(VISION_CV_CFLAGS)

VISION_LIB_SRCS := adapters/vision/vision_detect.c adapters/vision/vision_track.c adapters/vision/vision_msgmap.c \
    adapters/vision/vision_source.cpp adapters/vision/vision_component.c adapters/vision/vision_landmark.c
$(eval $(call marie_lib,vision,$(VISION_LIB_SRCS)))

$(eval $(call marie_program,marie-vision,adapters/vision/vision_main.c,$(VISION_LIBS)))
$(eval $(call marie_program,marie-vision-render,adapters/vision/vision_render_main.c,$(VISION_LIBS)))

$(eval $(call marie_test,test_vision_render,tests/vision/test_vision_render.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_track,tests/vision/test_vision_track.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_msgmap,tests/vision/test_vision_msgmap.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_image,tests/vision/test_vision_image.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_simcam,tests/vision/test_vision_simcam.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_transport,tests/vision/test_vision_transport.c,$(VISION_LIBS)))
$(eval $(call marie_test,test_vision_component,tests/vision/test_vision_component.c,$(VISION_LIBS)))
$(eval $(call marie_fuzz,vision_image,adapters/vision/fuzz_vision_image.c camera/vision_image.c,-ljpeg))
ITESTS += tests/vision/test_vision_process.sh

$(eval $(call marie_bench,bench_vision,bench/bench_vision.c,$(VISION_LIBS)))
# The vision adapter on the simulator's camera (processes on this test's bus).
$(eval $(call marie_test,test_vision_sim,tests/vision/test_vision_sim.c tests/proc.c,))
$(B)/tests/test_vision_sim: | $(B)/bin/marie-sim $(B)/bin/marie-vision
ITESTS += tests/vision/test_sign_mission.sh
