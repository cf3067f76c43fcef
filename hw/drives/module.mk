# hw/drives: CiA 402 wheel drives: state machine, master logic, virtual drive, marie-drives.
DRIVES_LIB := $(B)/lib/libmarie_drives.a
$(eval $(call marie_lib,marie_drives,hw/drives/cia402.c hw/drives/drives_ctl.c hw/drives/drives_text.c hw/drives/vdrive.c))
$(eval $(call marie_test,test_cia402,tests/hw/test_cia402.c,$(DRIVES_LIB)))
$(eval $(call marie_test,test_drives_ctl,tests/hw/test_drives_ctl.c,$(DRIVES_LIB) $(B)/lib/libmarie_gyro.a $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a))
$(eval $(call marie_program,marie-drives,hw/drives/drives_main.c,$(DRIVES_LIB) $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a))
VDEVICES_LIB := $(B)/lib/libmarie_vdevices.a
$(eval $(call marie_lib,marie_vdevices,hw/drives/vdevices.c))
$(eval $(call marie_program,marie-vcan-devices,hw/drives/vcan_devices_main.c,$(VDEVICES_LIB) $(DRIVES_LIB) $(B)/lib/libmarie_gyro.a $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a))
# Needs the programs: built first by make all; by hand, build them before this test.
$(eval $(call marie_test,test_drives_emu,tests/hw/test_drives_emu.c tests/proc.c,$(B)/lib/libmarie_can.a))
$(B)/tests/test_drives_emu: | $(B)/bin/marie-canbus $(B)/bin/marie-vcan-devices $(B)/bin/marie-drives $(B)/bin/marie-gyro
# python-canopen (PyPI, venv by scripts/peer-venv.sh) as an independent master against the
# virtual drives and gyro on the emulated bus; ~5 s plus the venv's first install.
ITESTS += tests/hw/test_canopen_peer.sh
# marie-drives against CiA 402 drives on python-canopen's LocalNode (tests/hw/cia402_slave.py),
# without 0x1016: configuration, RPDO deadline, restart interlock, refusal, named failures; ~40 s.
ITESTS += tests/hw/test_drives_peer.sh
# The VM test: marie-drives and marie-gyro on real SocketCAN (vcan0) inside qemu.
$(eval $(call marie_link,$(B)/tests/vm/hw_vm_check,tests/hw/vm_check.c,))
$(eval $(call marie_link,$(B)/tests/vm/vm_socketcan,tests/hw/vm_socketcan.c,$(B)/lib/libmarie_can.a -lcmocka))
EXTRA_TARGETS += $(B)/tests/vm/hw_vm_check $(B)/tests/vm/vm_socketcan
VMTESTS += tests/hw/test_vm_can.sh
# ~25 s here (boot ~6 s); also part of make test.
ITESTS += tests/hw/test_vm_can.sh
# The same checks on two emulated SJA1000 controllers (kvaser_pci) instead of vcan; ~60 s.
VMTESTS += tests/hw/test_vm_canctl.sh
ITESTS += tests/hw/test_vm_canctl.sh
$(eval $(call marie_bench,bench_hw_can,bench/bench_hw_can.c tests/proc.c,$(B)/lib/libmarie_can.a))
$(B)/bench/bench_hw_can: | $(B)/bin/marie-canbus $(B)/bin/marie-vcan-devices $(B)/bin/marie-drives $(B)/bin/marie-gyro
# For programs hosting the virtual devices (the simulator's device mode): link these.
HW_VDEVICES_LIBS := $(VDEVICES_LIB) $(DRIVES_LIB) $(B)/lib/libmarie_gyro.a $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a
