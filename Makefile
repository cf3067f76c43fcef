# marie: top-level build. Every folder adds its programs, tests and benchmarks in a
# module.mk fragment; all output goes under $(B) (build/, or build/san with SAN=1).

SAN ?= 0
ifeq ($(SAN),1)
B ?= build/san
else
B ?= build
endif
PREFIX ?= /usr/local
NPROC := $(shell nproc 2>/dev/null || echo 2)

CC  ?= gcc
CXX ?= g++
PKGS := lcm glib-2.0 libsodium
# Linked only into programs that call it (--as-needed below): core/bus opens liblcm itself
# when a bus needs it, so a component that marie's own bus serves loads neither liblcm nor
# glib and pcre2. libsodium is linked in (its archive): one library fewer to map and relocate
# at each start, and only the functions used.
# libfyaml is opened at run time by core/yaml.c (dlopen), so a process that has read its
# YAML can let it go: only its header is needed here.
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) libfyaml 2>/dev/null)
PKG_LIBS   := $(patsubst -lsodium,-l:libsodium.a,$(shell pkg-config --libs $(PKGS) 2>/dev/null))

# -Wno-missing-field-initializers: spec tables leave their optional trailing fields unset.
WARN     := -Wall -Wextra -Wno-unused-parameter -Wno-missing-field-initializers
CPPFLAGS := -I. -I$(B)/gen/c -I$(B)/gen/cpp $(PKG_CFLAGS) -D_GNU_SOURCE
# A section per function and datum, so the linker keeps only what a program reaches (libmarie
# and the generated types brought 350 kB of code into each driver, a third of it used), and
# relative relocations packed (DT_RELR: 1 kB instead of 30 kB read at every start).
SECTIONS := -ffunction-sections -fdata-sections
CFLAGS   := -O2 -g -std=gnu11 $(WARN) -MMD -MP $(SECTIONS)
CXXFLAGS := -O2 -g -std=gnu++17 $(WARN) -MMD -MP $(SECTIONS)
LDFLAGS  := -Wl,--gc-sections -Wl,-z,pack-relative-relocs -Wl,--as-needed
LDLIBS   := $(PKG_LIBS) -lm -lpthread
ifeq ($(SAN),1)
SANFLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
CFLAGS   += $(SANFLAGS) -O1
CXXFLAGS += $(SANFLAGS) -O1
LDFLAGS  += $(SANFLAGS)
endif

PROGRAMS :=
PY_PROGRAMS :=
TESTS    :=
ITESTS   :=
# make test's tests that need the cores to themselves: they run last, alone.
ALONE_TESTS :=
BENCHES  :=
BENCHES_FULL :=
FUZZERS  :=
LIBMARIE := $(B)/lib/libmarie.a

# $(call marie_objs,SOURCES): object files for C and C++ sources.
marie_objs = $(patsubst %.c,$(B)/obj/%.o,$(patsubst %.cpp,$(B)/obj/%.o,$(1)))

# $(call marie_lib,NAME,SOURCES): static library $(B)/lib/libNAME.a.
define marie_lib
$(B)/lib/lib$(1).a: $(call marie_objs,$(2))
	@mkdir -p $$(@D)
	@rm -f $$@
	$$(AR) rcs $$@ $$^
endef

# $(call marie_link,OUTPUT,SOURCES,LIBS): LIBS may hold .a paths (also prerequisites) and -l flags.
define marie_link
$(1): $(call marie_objs,$(2)) $(filter %.a,$(3)) $(LIBMARIE)
	@mkdir -p $$(@D)
	$$(CXX) $$(LDFLAGS) -o $$@ $$(filter %.o,$$^) $(3) $$(LIBMARIE) $$(LDLIBS)
endef

# $(call marie_program,NAME,SOURCES,LIBS): $(B)/bin/NAME, installed by make install.
define marie_program
$(call marie_link,$(B)/bin/$(1),$(2),$(3))
PROGRAMS += $(B)/bin/$(1)
endef

# $(call marie_py_program,NAME,SCRIPT): a Python component (python/marie, docs/python.md):
# $(B)/bin/NAME runs SCRIPT with marie's Python package and types; make install installs both.
define marie_py_program
$(B)/bin/$(1): $(2) python/wrapper.sh.in
	@mkdir -p $$(@D)
	sed -e 's|@NAME@|$(1)|g' -e 's|@SCRIPT@|$(CURDIR)/$(2)|g' -e 's|@BIN@|$(CURDIR)/$(B)/bin|g' \
	    -e 's|@PYPATH@|$(CURDIR)/python:$(CURDIR)/$(B)/python|g' python/wrapper.sh.in > $$@ && chmod 755 $$@
PY_PROGRAMS += $(1)=$(2)
EXTRA_TARGETS += $(B)/bin/$(1)
endef

# $(call marie_test,NAME,SOURCES,LIBS): cmocka test $(B)/tests/NAME, run by make test.
define marie_test
$(call marie_link,$(B)/tests/$(1),$(2),$(3) -lcmocka)
TESTS += $(B)/tests/$(1)
endef

# $(call marie_bench,NAME,SOURCES,LIBS): $(B)/bench/NAME, run by make bench; it prints
# TSV rows "bench metric value unit baseline ratio" on stdout.
define marie_bench
$(call marie_link,$(B)/bench/$(1),$(2),$(3))
BENCHES += $(B)/bench/$(1)
endef

# $(call marie_bench_full,NAME,SOURCES,LIBS): a benchmark too long for make bench's ten minutes
# (whole evaluations over many worlds or logs): run by make bench-full, after the default set.
define marie_bench_full
$(call marie_link,$(B)/bench/$(1),$(2),$(3))
BENCHES_FULL += $(B)/bench/$(1)
endef

# $(call marie_fuzz,NAME,SOURCES,LIBS): SOURCES define LLVMFuzzerTestOneInput; the seed corpus
# is tests/data/fuzz/NAME/. make test runs the replay build over the corpus plus seeded
# mutations; make fuzz runs libFuzzer on it.
define marie_fuzz
$(call marie_link,$(B)/tests/fuzz_$(1),tests/fuzz_main.c $(2),$(3))
TESTS += $(B)/tests/fuzz_$(1)
FUZZ_$(1)_SOURCES := $(2)
FUZZ_$(1)_LIBS := $(3)
FUZZERS += $(1)
endef

.PHONY: build all deps test-deps test test-slow test-vm test-fresh bench bench-full demo install fuzz clean
# `make` alone installs what is missing first, like the other verbs; `all` only builds.
build: deps
	@$(MAKE) -j$(NPROC) --no-print-directory all
all:

include lcmtypes/module.mk
include core/module.mk
include map/module.mk
include camera/module.mk
include proto/module.mk
include $(sort $(filter-out core/module.mk lcmtypes/module.mk map/module.mk camera/module.mk proto/module.mk,$(wildcard */module.mk */*/module.mk)))

# Parameters are declared once, in NAME.params.yaml beside the component's or library's code:
# the struct, spec tables and defaults are generated into $(B)/gen/c/DIR/NAME_params.h
# (core/params_gen.py, docs/core.md).
PARAM_SPECS := $(sort $(wildcard */*.params.yaml */*/*.params.yaml))
PARAM_HEADERS := $(patsubst %.params.yaml,$(B)/gen/c/%_params.h,$(PARAM_SPECS))
GEN_HEADERS += $(PARAM_HEADERS)
.SECONDARY: $(PARAM_HEADERS)
$(B)/gen/c/%_params.h: %.params.yaml core/params_gen.py
	@mkdir -p $(@D)
	python3 core/params_gen.py $< $@

all: $(LIBMARIE) $(PROGRAMS) $(TESTS) $(BENCHES) $(BENCHES_FULL) $(EXTRA_TARGETS)

$(B)/obj/%.o: %.c | $(GEN_HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c -o $@ $<
$(B)/obj/%.o: %.cpp | $(GEN_HEADERS)
	@mkdir -p $(@D)
	$(CXX) $(CPPFLAGS) $(CXXFLAGS) -c -o $@ $<

deps:
	@scripts/install-deps.sh base

# Tests also need qemu (real SocketCAN in a VM) and Chromium (the log viewer's page).
test-deps: deps
	@scripts/install-deps.sh vm browser

# Each test runs in its own network namespace (so the PyPI witnesses' venv is made before,
# outside): the test programs NPROC + 1 at a time (NPROC under SAN), the longest of the last
# run first: most of their time is waiting (a reply, a timeout, a restart), 3 at a time took
# phase one from 135 s to 100 s here, longest first to ~97 s. Then the other shell tests (whole
# systems, VMs, browsers, loads and timings) one by one, alone but for those of one
# "# test-group: NAME", which run side by side: `vm-managers`, the three one-CPU VM tests
# (margins of an emulated CPU) with the three manager tests that measure loads against the
# kernel's count (am, balance, top): 55-58 s together, 94 + 91 s one after the other;
# `robot`, the robot application's missions (test_robot_app, the spoken mission at real time)
# with the log viewer's page (50 s together, 126 s one after the other). (One run with the VM
# and manager tests together had a VM that never reached init within its 240 s: a VM not
# started within 60 s is now booted again, scripts/vm/run-in-vm.sh.) From the start, beside
# all of these, the light shell tests (those that mostly wait and time nothing that busy cores
# would break: "# test-light" in their head) run two at a time (LIGHT_LANES; 297 s one by one).
# Last, once all that is done, the ALONE_TESTS, one by one. The last line is the summary. (All
# side by side took 3 min 54 s, 4 at a time, but the test programs' timing checks, the LMS200
# driver's 150 ms replies and the simulator's device heartbeats, then failed beside a whole
# robot or a VM.)
TEST_JOBS := $(if $(filter 1,$(SAN)),$(NPROC),$(shell echo $$(($(NPROC) + 1))))
test: test-deps
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) scripts/peer-venv.sh >/dev/null
	@B=$(B) SAN=$(SAN) scripts/run-tests.sh --jobs $(TEST_JOBS) $(TESTS) -- $(ITESTS) -- $(ALONE_TESTS)

# Long end-to-end runs kept out of make test's 10 minutes on two cores (each says why in its module.mk).
test-slow: test-deps
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) SAN=$(SAN) TEST_TIMEOUT=$${TEST_TIMEOUT:-600} scripts/run-tests.sh $(SLOW_TESTS)

test-vm: deps
	@scripts/install-deps.sh vm
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) scripts/run-tests.sh $(VMTESTS)

# The README's two commands on a brand-new Debian 12 root filesystem (slow: docs/testing.md).
test-fresh:
	@scripts/install-deps.sh fresh
	@scripts/test-fresh.sh

bench: deps
	@scripts/install-deps.sh bench
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) scripts/peer-venv.sh >/dev/null
	@B=$(B) scripts/run-bench.sh $(BENCHES)

# The default set, then the long evaluations; the same table and results file.
bench-full: deps
	@scripts/install-deps.sh bench
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) scripts/peer-venv.sh >/dev/null
	@B=$(B) scripts/run-bench.sh $(BENCHES) $(BENCHES_FULL)

demo: deps
	@$(MAKE) -j$(NPROC) --no-print-directory all
	@B=$(B) scripts/demo.sh

# libFuzzer builds compile the target's SOURCES and libmarie's with clang's instrumentation.
fuzz: deps all
	@scripts/install-deps.sh san
	@mkdir -p $(B)/fuzz
	@set -e; for f in $(FUZZERS); do \
	    echo "fuzz: $$f for $(or $(FUZZ_SECONDS),30) s"; \
	    $(MAKE) --no-print-directory -s $(B)/fuzz/$$f; \
	    mkdir -p $(B)/fuzz/corpus-$$f; \
	    LSAN_OPTIONS=suppressions=tests/lsan.supp $(B)/fuzz/$$f -max_total_time=$(or $(FUZZ_SECONDS),30) \
	        -artifact_prefix=$(B)/fuzz/ -print_final_stats=1 \
	        $(B)/fuzz/corpus-$$f tests/data/fuzz/$$f 2>&1 | tail -3; \
	done

# A fuzzer is built again when its own sources change too (secondary expansion names them).
.SECONDEXPANSION:
$(B)/fuzz/%: $(LIBMARIE) $$(FUZZ_$$*_SOURCES)
	@mkdir -p $(@D)
	clang -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize=nonnull-attribute $(CPPFLAGS) -o $@ $(FUZZ_$*_SOURCES) $(CORE_SRCS) \
	    $(LCM_C_SRCS) $(FUZZ_$*_LIBS) $(LDLIBS) -lstdc++

install: all
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig \
	    $(DESTDIR)$(PREFIX)/include/marie/core/bus $(DESTDIR)$(PREFIX)/include/marie/lcmtypes
	install -m 755 $(PROGRAMS) $(DESTDIR)$(PREFIX)/bin/
	install -m 644 $(LIBMARIE) $(DESTDIR)$(PREFIX)/lib/
	install -m 644 $(filter-out %_priv.h,$(wildcard core/*.h)) $(DESTDIR)$(PREFIX)/include/marie/core/
	install -m 644 $(wildcard core/bus/*.h) $(DESTDIR)$(PREFIX)/include/marie/core/bus/
	install -m 644 $(B)/gen/c/lcmtypes/*.h $(DESTDIR)$(PREFIX)/include/marie/lcmtypes/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@REQUIRES@|$(PKGS)|' -e 's|@SANFLAGS@|$(SANFLAGS)|' core/marie.pc.in \
	    > $(DESTDIR)$(PREFIX)/lib/pkgconfig/marie.pc
	$(INSTALL_EXTRA)

clean:
	rm -rf build

-include $(shell find $(B)/obj -name '*.d' 2>/dev/null)
-include $(PARAM_HEADERS:.h=.d)
