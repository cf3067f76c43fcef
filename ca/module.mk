# ca: the Communication Adapters (Mailbox, Splitter, SharedMap, Switch) as libca and marie-ca.
CA_LIB_SRCS := ca/ca.c ca/mailbox.c ca/sharedmap.c ca/sharedmap_log.c ca/sharedmap_client.c ca/splitter.c ca/switch.c
$(eval $(call marie_lib,ca,$(CA_LIB_SRCS)))
LIBCA := $(B)/lib/libca.a

$(eval $(call marie_program,marie-ca,ca/ca_main.c,$(LIBCA)))

# Unit tests of the pure logic (no process).
$(eval $(call marie_test,test_ca_mailbox,tests/ca/test_mailbox.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_sharedmap,tests/ca/test_sharedmap.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_sharedmap_damage,tests/ca/test_sharedmap_damage.c tests/ca/sharedmap_damage.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_splitter,tests/ca/test_splitter.c,$(LIBCA)))
$(eval $(call marie_test,test_ca_switch,tests/ca/test_switch.c,$(LIBCA)))

# Tests of marie-ca processes over real LCM.
CA_TESTLIB := tests/ca/ca_test.c tests/proc.c
CA_BUS_TESTS := test_ca_mailbox_bus test_ca_sharedmap_bus test_ca_sharedmap_crash test_ca_switch_bus \
                test_ca_splitter_bus test_ca_config test_ca_sharedmap_durability test_ca_sharedmap_recovery
$(foreach t,$(CA_BUS_TESTS),$(eval $(call marie_test,$(t),tests/ca/$(patsubst test_ca_%,test_%,$(t)).c $(CA_TESTLIB),$(LIBCA))))
$(patsubst %,$(B)/tests/%,$(CA_BUS_TESTS)): | $(B)/bin/marie-ca

# Preloaded into marie-ca by test_ca_sharedmap_durability and _crash: traces log writes,
# syncs and sends in order, or holds writes until their sync to play a power loss (plain
# flags: it must not carry the sanitizers into the traced process).
$(B)/tests/libca_syncshim.so: tests/ca/syncshim.c
	@mkdir -p $(@D)
	$(CC) -shared -fPIC -O2 -Wall -Wextra -o $@ $< -ldl
$(B)/tests/test_ca_sharedmap_durability $(B)/tests/test_ca_sharedmap_crash: | $(B)/tests/libca_syncshim.so

# Request decoders on arbitrary bytes. make fuzz builds with clang from sources only (it
# leaves .a files out), so list what libca needs.
$(eval $(call marie_fuzz,ca_requests,tests/ca/fuzz_requests.c,$(LIBCA)))
FUZZ_ca_requests_SOURCES := tests/ca/fuzz_requests.c $(CA_LIB_SRCS) core/time.c $(LCM_C_SRCS)

# Benchmark: each CA process against a plain LCM relay process in the same run.
$(eval $(call marie_link,$(B)/bench/ca-lcm-relay,tests/ca/lcm_relay.c,$(LIBCA)))
$(eval $(call marie_bench,bench_ca,bench/bench_ca.c $(CA_TESTLIB),$(LIBCA)))
$(B)/bench/bench_ca: $(B)/bench/ca-lcm-relay | $(B)/bin/marie-ca

# SharedMap state files, damaged or hostile.
$(eval $(call marie_fuzz,ca_sharedmap_log,tests/ca/fuzz_sharedmap_log.c tests/ca/sharedmap_damage.c,$(LIBCA)))
FUZZ_ca_sharedmap_log_SOURCES := tests/ca/fuzz_sharedmap_log.c tests/ca/sharedmap_damage.c $(CA_LIB_SRCS) core/time.c $(LCM_C_SRCS)
