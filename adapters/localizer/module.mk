# adapters/localizer: marie-localizer (Monte Carlo localization and global relocalization; Eigen).
include adapters/common/adapters.mk
$(B)/obj/adapters/localizer/%.o: CPPFLAGS += $(ADAPT_EIGEN_CFLAGS)
LOC_CORE := adapters/localizer/mcl.cpp adapters/localizer/field.cpp adapters/localizer/reloc.cpp adapters/localizer/seek.c
$(eval $(call marie_program,marie-localizer,adapters/localizer/localizer_main.c $(LOC_CORE),$(ADAPT_COMMON)))
$(eval $(call marie_test,test_mcl,tests/adapters/test_mcl.c $(LOC_CORE),$(ADAPT_COMMON)))
