# tests/hw: the VM tests' helpers that are not a driver's: a real GPIO line (gpio-sim) and
# real CAN controllers (qemu's kvaser_pci, sja1000 driver), both inside qemu.
$(eval $(call marie_link,$(B)/tests/vm/vm_gpio_check,tests/hw/vm_gpio_check.c,))
EXTRA_TARGETS += $(B)/tests/vm/vm_gpio_check
# 100-135 s here on a loaded machine (boot ~10 s); the module build (~2 min, once per machine) is done by
# scripts/install-deps.sh vm before the tests.
VMTESTS += tests/hw/test_vm_gpio.sh
ITESTS += tests/hw/test_vm_gpio.sh
# 140-210 s here on a loaded machine (boot ~15 s: the two boards take a while to probe).
VMTESTS += tests/hw/test_vm_can_ctrl.sh
ITESTS += tests/hw/test_vm_can_ctrl.sh
