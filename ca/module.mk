# ca: the Communication Adapters (Mailbox, Splitter, SharedMap, Switch) as libca and marie-ca.
CA_LIB_SRCS := ca/ca.c ca/mailbox.c ca/sharedmap.c ca/sharedmap_client.c ca/splitter.c ca/switch.c
$(eval $(call marie_lib,ca,$(CA_LIB_SRCS)))
LIBCA := $(B)/lib/libca.a

$(eval $(call marie_test,test_ca_mailbox,tests/ca/test_mailbox.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_sharedmap,tests/ca/test_sharedmap.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_splitter,tests/ca/test_splitter.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_switch,tests/ca/test_switch.c,$(LIBCA)))
$(eval $(call marie_program,marie-ca,ca/ca_main.c,$(LIBCA)))
CA_TESTLIB := tests/ca/ca_test.c
$(eval $(call marie_test,test_ca_mailbox_bus,tests/ca/test_mailbox_bus.c $(CA_TESTLIB),$(LIBCA)))
$(eval $(call marie_test,test_ca_sharedmap_bus,tests/ca/test_sharedmap_bus.c $(CA_TESTLIB),$(LIBCA)))
$(eval $(call marie_test,test_ca_sharedmap_crash,tests/ca/test_sharedmap_crash.c $(CA_TESTLIB),$(LIBCA)))
$(eval $(call marie_test,test_ca_switch_bus,tests/ca/test_switch_bus.c $(CA_TESTLIB),$(LIBCA)))
$(eval $(call marie_test,test_ca_splitter_bus,tests/ca/test_splitter_bus.c $(CA_TESTLIB),$(LIBCA)))
$(eval $(call marie_fuzz,ca_requests,tests/ca/fuzz_requests.c,$(LIBCA)))

# Benchmark: each CA process against a plain LCM relay process in the same run.
$(eval $(call marie_link,$(B)/bench/ca-lcm-relay,tests/ca/lcm_relay.c,$(LIBCA)))
$(eval $(call marie_bench,bench_ca,tests/ca/bench_ca.c $(CA_TESTLIB),$(LIBCA)))
$(B)/bench/bench_ca: $(B)/bench/ca-lcm-relay
$(eval $(call marie_test,test_ca_config,tests/ca/test_config.c $(CA_TESTLIB),$(LIBCA)))
# make fuzz builds with clang from sources only (it leaves .a files out): list what libca needs.
FUZZ_ca_requests_SOURCES := tests/ca/fuzz_requests.c $(CA_LIB_SRCS) core/time.c $(LCM_C_SRCS)
