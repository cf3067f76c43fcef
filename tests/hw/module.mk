# tests/hw: the VM test of a real GPIO line (gpio-sim inside qemu) and its helper. (The real CAN
# controllers' VM test is hw/drives' test_vm_canctl.sh.)
$(eval $(call marie_link,$(B)/tests/vm/vm_gpio_check,tests/hw/vm_gpio_check.c,))
EXTRA_TARGETS += $(B)/tests/vm/vm_gpio_check
# 40 s here (boot 6 s), up to 135 s on a loaded machine; the module build (~2 min, once per machine) is done by
# scripts/install-deps.sh vm before the tests.
VMTESTS += tests/hw/test_vm_gpio.sh
ITESTS += tests/hw/test_vm_gpio.sh
