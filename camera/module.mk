# camera: libmarie_camera, camera models and the synthetic camera (pinhole geometry, tag
# families, marie.image_t coding, tags and walls rendered for a robot in a 2D world), shared
# by marie-vision, the simulator, tests and benchmarks. The headers need no OpenCV.
CAMERA_CV_CFLAGS := $(shell pkg-config --cflags opencv4 2>/dev/null)
# Debian's libapriltag exports only the detector; image_u8 helpers live in libapriltag-utils.
CAMERA_LIBS := $(B)/lib/libmarie_camera.a $(MAP_LIB) -lopencv_imgcodecs -lopencv_imgproc -lopencv_core \
    -lapriltag -lapriltag-utils -ljpeg
$(B)/obj/camera/%.o: CPPFLAGS += $(CAMERA_CV_CFLAGS)

$(eval $(call marie_lib,marie_camera,camera/vision_geom.c camera/vision_family.c camera/vision_render.cpp \
    camera/vision_image.c camera/vision_image_encode.cpp camera/vision_simcam.c))
