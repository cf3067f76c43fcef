# managers: marie-am (one per host), the marie command line, and their library (the order
# protocol they share with the tools is proto/'s).
MANAGERS_LIB := $(B)/lib/libmarie_managers.a $(PROTO_LIB)
$(eval $(call marie_lib,marie_managers,managers/am_settings.c managers/logcap.c managers/progcheck.c managers/spawn.c managers/supervise.c managers/balance.c managers/limits.c))

# marie-am: I/O (am.c main, am_run.c spawn and actions, am_output.c output capture,
# am_status.c, am_system.c, am_orders.c, am_check.c: an up order's program check in a child,
# am_apply.c: an up of a changed system applied as a difference, am_balance.c: placement,
# am_limits.c: resource limits, sdnotify.c: systemd's notify protocol) around the pure parts in
# the library (supervise.c, balance.c, limits.c). Each file owns one part of struct am (am.h).
$(eval $(call marie_program,marie-am,managers/am.c managers/am_run.c managers/am_output.c managers/am_status.c managers/am_system.c managers/am_orders.c managers/am_check.c managers/am_apply.c managers/am_balance.c managers/am_limits.c managers/sdnotify.c,$(MANAGERS_LIB)))
$(eval $(call marie_program,marie,managers/marie.c managers/marie_bus.c managers/marie_cmds.c managers/marie_doctor.c,$(MANAGERS_LIB)))

# The systemd unit, with the install prefix substituted.
INSTALL_EXTRA += install -d $(DESTDIR)$(PREFIX)/lib/systemd/system && sed "s|/usr/local/|$(PREFIX)/|g" deploy/systemd/marie-am.service > $(DESTDIR)$(PREFIX)/lib/systemd/system/marie-am.service && chmod 644 $(DESTDIR)$(PREFIX)/lib/systemd/system/marie-am.service;

# Test helpers (not installed): a component that can be made to hang, crash or print, a
# sender of hand-made (unsigned, forged, replayed, malformed) orders, and a flood of status
# requests or a manager that does not answer them.
$(eval $(call marie_link,$(B)/tests/bin/marie-test-comp,tests/managers/test_comp.c,))
$(eval $(call marie_link,$(B)/tests/bin/marie-test-order,tests/managers/order_tool.c,$(MANAGERS_LIB)))
$(eval $(call marie_link,$(B)/tests/bin/marie-test-status,tests/managers/status_tool.c,$(MANAGERS_LIB)))
EXTRA_TARGETS += $(B)/tests/bin/marie-test-comp $(B)/tests/bin/marie-test-order $(B)/tests/bin/marie-test-status

$(eval $(call marie_test,test_auth,tests/managers/test_auth.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_logcap,tests/managers/test_logcap.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_spawn,tests/managers/test_spawn.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_supervise,tests/managers/test_supervise.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_limits,tests/managers/test_limits.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_am_wire,tests/managers/test_am_wire.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_am_notify,tests/managers/test_am_notify.c,))
$(eval $(call marie_test,test_sdnotify,tests/managers/test_sdnotify.c managers/sdnotify.c,))
$(eval $(call marie_test,test_progcheck,tests/managers/test_progcheck.c,$(MANAGERS_LIB)))
ITESTS += tests/managers/test_am.sh tests/managers/test_am_spawn.sh tests/managers/test_up_check.sh tests/managers/test_up_refuses.sh tests/managers/test_limits.sh tests/managers/test_multihost.sh tests/managers/test_systemd.sh
ITESTS += tests/managers/test_balance.sh tests/managers/test_ps.sh tests/managers/test_sched.sh tests/managers/test_up_apply.sh
# Its two busy loops load both cores and a 0.3 s heartbeat must still get through: with a light
# test beside them it saw false restarts, so it runs last in make test, alone.
ALONE_TESTS += tests/managers/test_fast_detect.sh
# make fuzz links only the listed sources: the generated decoders it needs are listed too.
$(eval $(call marie_fuzz,am_order,tests/managers/fuzz_am_order.c managers/logcap.c,))

$(eval $(call marie_bench,bench_am,bench/bench_am.c tests/proc.c,$(MANAGERS_LIB)))

# marie top: the live system in a terminal; its table model is a pure module, unit-tested.
$(eval $(call marie_program,marie-top,managers/top_main.c managers/top.c,))
$(eval $(call marie_test,test_balance,tests/managers/test_balance.c,$(MANAGERS_LIB)))
$(eval $(call marie_test,test_top,tests/managers/test_top.c managers/top.c,))
ITESTS += tests/managers/test_top.sh
# Two competing loads for five minutes: no flapping (lasts five minutes by design).
SLOW_TESTS += tests/managers/test_balance_loads.sh
# Limits held by cgroup v2 need a kernel whose cgroup v2 has the memory and cpu controllers: a VM
# (about 30 s; alone, not beside the other VMs, whose margins were measured without it).
ITESTS += tests/managers/test_vm_limits.sh
VMTESTS += tests/managers/test_vm_limits.sh
ITESTS += tests/managers/test_doctor_readme.sh
