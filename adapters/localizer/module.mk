# adapters/localizer: marie-localizer (Monte Carlo localization; Eigen and OpenCV).
include adapters/common/adapters.mk
$(B)/obj/adapters/localizer/%.o: CPPFLAGS += $(ADAPT_EIGEN_CFLAGS)
$(eval $(call marie_program,marie-localizer,adapters/localizer/localizer_main.c adapters/localizer/mcl.cpp,$(ADAPT_COMMON) $(ADAPT_CV_LIBS)))
$(eval $(call marie_test,test_mcl,tests/adapters/test_mcl.c adapters/localizer/mcl.cpp,$(ADAPT_COMMON) $(ADAPT_CV_LIBS)))
