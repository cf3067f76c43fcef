# adapters/odometry: marie-odometry (wheel encoders + gyro fusion at 10 Hz).
include adapters/common/adapters.mk
$(eval $(call marie_lib,odo,adapters/odometry/odo.c))
$(eval $(call marie_program,marie-odometry,adapters/odometry/odometry_main.c,$(B)/lib/libodo.a))
$(eval $(call marie_test,test_odo,tests/adapters/test_odo.c,$(B)/lib/libodo.a))
$(eval $(call marie_test,test_odometry_gyro,tests/adapters/test_odometry_gyro.c tests/proc.c))
