# adapters/common/adapters.mk: build settings shared by the adapters' module.mk fragments
# (included by each, since fragments are read in alphabetical order).
ADAPT_COMMON := $(B)/lib/libadaptcommon.a $(MAP_LIB)
ADAPT_CV_LIBS := -lopencv_imgproc -lopencv_core
ADAPT_EIGEN_CFLAGS := -I/usr/include/eigen3 -I/usr/include/opencv4
ADAPT_OMPL_CFLAGS := -I/usr/include/ompl-1.5 $(ADAPT_EIGEN_CFLAGS)
ADAPT_OMPL_LIBS := $(filter-out -L%,$(shell pkg-config --libs ompl 2>/dev/null)) $(ADAPT_CV_LIBS)
