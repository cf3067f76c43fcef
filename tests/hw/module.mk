# tests/hw: the VM tests' helpers that are not a driver's: a real GPIO line (gpio-sim) and
# real CAN controllers (qemu's kvaser_pci, sja1000 driver), both inside qemu.
$(eval $(call marie_link,$(B)/tests/vm/vm_gpio_check,tests/hw/vm_gpio_check.c,))
EXTRA_TARGETS += $(B)/tests/vm/vm_gpio_check
# 40 s here (boot 6 s), up to 135 s on a loaded machine; the module build (~2 min, once per machine) is done by
# scripts/install-deps.sh vm before the tests.
VMTESTS += tests/hw/test_vm_gpio.sh
ITESTS += tests/hw/test_vm_gpio.sh
# 52 s here (boot 7 s), up to 210 s on a loaded machine.
VMTESTS += tests/hw/test_vm_can_ctrl.sh
ITESTS += tests/hw/test_vm_can_ctrl.sh
