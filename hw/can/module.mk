# hw/can: CAN frame I/O (SocketCAN or the emulated bus) and the marie-canbus daemon.
CAN_LIB := $(B)/lib/libmarie_can.a
$(eval $(call marie_lib,marie_can,hw/can/can.c hw/can/canbus.c hw/can/can_link.c))
$(eval $(call marie_program,marie-canbus,hw/can/canbus_main.c,$(CAN_LIB)))
$(eval $(call marie_program,marie-candump,hw/can/candump_main.c,$(CAN_LIB)))
$(eval $(call marie_test,test_can,tests/hw/test_can.c,$(CAN_LIB)))
