# hw/gpio: e-stop input (debounced edge events) and status LED over libgpiod.
GPIO_LIB := $(B)/lib/libmarie_gpio.a
$(eval $(call marie_lib,marie_gpio,hw/gpio/debounce.c hw/gpio/gpio.c))

$(eval $(call marie_program,marie-gpio,hw/gpio/gpio_main.c,$(GPIO_LIB) -lgpiod))

$(eval $(call marie_test,test_gpio_debounce,tests/hw/test_gpio_debounce.c,$(GPIO_LIB)))
$(eval $(call marie_test,test_gpio_component,tests/hw/test_gpio_component.c))
$(B)/tests/test_gpio_component: $(B)/bin/marie-gpio
