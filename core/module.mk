# core: libmarie (component runtime, loop, config, logging) with the generated LCM types.
CORE_SRCS := $(sort $(wildcard core/*.c core/bus/*.c))

$(LIBMARIE): $(call marie_objs,$(CORE_SRCS)) $(LCM_OBJS)
	@mkdir -p $(@D)
	@rm -f $@
	$(AR) rcs $@ $^

# tests/core/test_NAME.c, each a program of its own
CORE_TESTS := loop base64 buf cli config config_entry spec typeinfo expand shm
$(foreach t,$(CORE_TESTS),$(eval $(call marie_test,test_$(t),tests/core/test_$(t).c)))
$(foreach t,lcm lifecycle,$(eval $(call marie_test,test_$(t),tests/core/test_$(t).c tests/udp.c)))
$(eval $(call marie_test,test_ports,tests/core/test_ports.c tests/proc.c))
$(eval $(call marie_test,test_local,tests/core/test_local.c tests/proc.c))
$(eval $(call marie_test,test_shm_bus,tests/core/test_shm_bus.c tests/proc.c))
# Its two busy loops hold both cores: it runs last in make test, alone.
$(eval $(call marie_link,$(B)/tests/test_burst,tests/core/test_burst.c tests/proc.c,-lcmocka))
EXTRA_TARGETS += $(B)/tests/test_burst
ALONE_TESTS += $(B)/tests/test_burst
$(eval $(call marie_fuzz,config,tests/core/fuzz_config.c))
$(eval $(call marie_fuzz,config_entry,tests/core/fuzz_config_entry.c))
$(eval $(call marie_fuzz,config_plain,tests/core/fuzz_config_plain.c))
$(eval $(call marie_fuzz,typeinfo,tests/core/fuzz_typeinfo.c))
$(eval $(call marie_bench,bench_ports,bench/bench_ports.c tests/proc.c))
ITESTS += tests/core/test_decode_rule.sh
$(eval $(call marie_link,$(B)/tests/malformed_peer,tests/core/malformed_peer.c,))
EXTRA_TARGETS += $(B)/tests/malformed_peer
ITESTS += tests/core/test_malformed_inputs.sh
$(eval $(call marie_link,$(B)/tests/lcm_send,tests/core/lcm_send.c,))
EXTRA_TARGETS += $(B)/tests/lcm_send
ITESTS += tests/core/test_lcm_python_peer.sh
$(eval $(call marie_fuzz,shm,tests/core/fuzz_shm.c))
$(eval $(call marie_fuzz,local,tests/core/fuzz_local.c))
$(eval $(call marie_fuzz,lcm,tests/core/fuzz_lcm.c tests/udp.c))
ITESTS += tests/core/test_params_gen.sh
# marie-params-gen: the generator, installed for users' components (docs/core.md, "Parameters").
$(B)/bin/marie-params-gen: core/params_gen.py
	@mkdir -p $(@D)
	cp $< $@ && chmod 755 $@
EXTRA_TARGETS += $(B)/bin/marie-params-gen
INSTALL_EXTRA += install -m 755 $(B)/bin/marie-params-gen $(DESTDIR)$(PREFIX)/bin/;
