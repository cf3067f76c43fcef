# adapters/behaviours: marie-behaviours (behaviours and priority arbitration at 5 Hz).
include adapters/common/adapters.mk
$(eval $(call marie_lib,arbiter,adapters/behaviours/arbiter.c adapters/behaviours/recovery.c))
$(eval $(call marie_program,marie-behaviours,adapters/behaviours/behaviours_main.c,$(B)/lib/libarbiter.a))
$(eval $(call marie_test,test_arbiter,tests/adapters/test_arbiter.c,$(B)/lib/libarbiter.a))
