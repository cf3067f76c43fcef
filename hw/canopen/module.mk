# hw/canopen: pure CiA 301 protocol pieces (NMT, heartbeat, SYNC, SDO, PDO, EMCY, device node).
CANOPEN_LIB := $(B)/lib/libmarie_canopen.a
$(eval $(call marie_lib,marie_canopen,hw/canopen/nmt.c hw/canopen/sdo.c hw/canopen/pdo.c hw/canopen/emcy.c hw/canopen/dev.c))
$(eval $(call marie_test,test_canopen,tests/hw/test_canopen.c,$(CANOPEN_LIB)))
$(eval $(call marie_fuzz,canopen,tests/hw/fuzz_canopen.c hw/canopen/nmt.c hw/canopen/sdo.c hw/canopen/pdo.c hw/canopen/emcy.c hw/canopen/dev.c hw/drives/cia402.c hw/drives/drives_ctl.c hw/drives/vdrive.c hw/gyro/gyro_ctl.c hw/gyro/vgyro.c))
