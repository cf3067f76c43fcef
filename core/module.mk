# core: libmarie (component runtime, loop, config, logging) with the generated LCM types.
CORE_SRCS := $(sort $(wildcard core/*.c))

$(LIBMARIE): $(call marie_objs,$(CORE_SRCS)) $(LCM_OBJS)
	@mkdir -p $(@D)
	@rm -f $@
	$(AR) rcs $@ $^

$(eval $(call marie_test,test_loop,tests/core/test_loop.c))
$(eval $(call marie_test,test_base64,tests/core/test_base64.c))
$(eval $(call marie_test,test_buf,tests/core/test_buf.c))
$(eval $(call marie_test,test_config,tests/core/test_config.c))
$(eval $(call marie_test,test_spec,tests/core/test_spec.c))
$(eval $(call marie_test,test_lifecycle,tests/core/test_lifecycle.c))
$(eval $(call marie_test,test_ports,tests/core/test_ports.c tests/proc.c))
$(eval $(call marie_fuzz,config,tests/core/fuzz_config.c))
$(eval $(call marie_test,test_typeinfo,tests/core/test_typeinfo.c))
$(eval $(call marie_test,test_expand,tests/core/test_expand.c))
$(eval $(call marie_test,test_shm,tests/core/test_shm.c))
$(eval $(call marie_test,test_shm_bus,tests/core/test_shm_bus.c))
$(eval $(call marie_fuzz,typeinfo,tests/core/fuzz_typeinfo.c))
$(eval $(call marie_bench,bench_ports,bench/bench_ports.c tests/proc.c))
ITESTS += tests/core/test_decode_rule.sh
$(eval $(call marie_link,$(B)/tests/malformed_peer,tests/core/malformed_peer.c,))
EXTRA_TARGETS += $(B)/tests/malformed_peer
ITESTS += tests/core/test_malformed_inputs.sh
$(eval $(call marie_fuzz,shm,tests/core/fuzz_shm.c))
ITESTS += tests/core/test_params_gen.sh
