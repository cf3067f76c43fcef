# hw/gyro: CANopen yaw-rate gyro: master logic, bias estimator, virtual gyro, marie-gyro.
GYRO_LIB := $(B)/lib/libmarie_gyro.a
$(eval $(call marie_lib,marie_gyro,hw/gyro/gyro_ctl.c hw/gyro/gyro_bias.c hw/gyro/vgyro.c))
$(eval $(call marie_test,test_gyro,tests/hw/test_gyro.c,$(GYRO_LIB) $(B)/lib/libmarie_canopen.a))
$(eval $(call marie_program,marie-gyro,hw/gyro/gyro_main.c,$(GYRO_LIB) $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a))
ITESTS += tests/hw/test_gyro_ps.sh
