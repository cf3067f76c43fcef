# lcmtypes: generate C, C++ and Java from the .lcm files, plus marie's C type registry.
LCM_FILES := $(sort $(wildcard lcmtypes/*.lcm))
LCM_NAMES := $(basename $(notdir $(LCM_FILES)))
GEN_HEADERS := $(B)/gen/c/lcmtypes/marie_types.h
LCM_C_SRCS := $(patsubst %,$(B)/gen/c/lcmtypes/marie_%.c,$(LCM_NAMES)) $(B)/gen/c/lcmtypes/marie_types.c \
              $(B)/gen/c/lcmtypes/marie_typeinfo.c
LCM_JAR := $(B)/java/marie_types.jar

$(B)/gen/c/lcmtypes/marie_types.h: $(LCM_FILES) scripts/gen-type-registry.sh
	@mkdir -p $(B)/gen/c/lcmtypes $(B)/gen/cpp
	lcm-gen -c --c-cpath $(B)/gen/c/lcmtypes --c-hpath $(B)/gen/c/lcmtypes --cinclude lcmtypes $(LCM_FILES)
	lcm-gen -x --cpp-std c++11 --cpp-hpath $(B)/gen/cpp $(LCM_FILES)
	scripts/gen-type-registry.sh $(B)/gen/c/lcmtypes $(LCM_NAMES)
	@# the .c files are written before the header: make them newer so that nothing is rebuilt twice
	@touch $(filter-out %/marie_typeinfo.c,$(LCM_C_SRCS))

$(filter-out %/marie_types.c %/marie_typeinfo.c,$(LCM_C_SRCS)) $(B)/gen/c/lcmtypes/marie_types.c: $(B)/gen/c/lcmtypes/marie_types.h ;

# Field-level descriptors of every type (core/typeinfo.h): the payload checker and the XML bridge.
$(B)/gen/c/lcmtypes/marie_typeinfo.c: $(LCM_FILES) lcmtypes/typeinfo_gen.py
	@mkdir -p $(@D)
	python3 lcmtypes/typeinfo_gen.py table $@ $(LCM_FILES)

# LCM's inline codec (lcm_coretypes.h) calls memcpy(NULL, ..., 0) for empty arrays, which
# UBSan reports; that one check is off for generated code only.
GEN_CFLAGS := $(if $(filter 1,$(SAN)),-fno-sanitize=nonnull-attribute)
# Their publish and subscribe functions call core/bus's stand-ins for liblcm's, which serve a
# bus marie reads itself and pass any other to liblcm: a program using the types alone does not
# load liblcm (docs/managers.md, "What one start costs").
GEN_CFLAGS += $(foreach f,publish subscribe unsubscribe subscription_set_queue_capacity,-Dlcm_$(f)=marie_lcm_$(f))
$(B)/obj/gen/%.o: $(B)/gen/c/lcmtypes/%.c $(GEN_HEADERS) lcmtypes/module.mk
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) $(GEN_CFLAGS) -Wno-unused-function -c -o $@ $<

LCM_OBJS := $(patsubst $(B)/gen/c/lcmtypes/%.c,$(B)/obj/gen/%.o,$(LCM_C_SRCS))

# The Java jar is what lcm-spy loads to decode marie's types.
$(LCM_JAR): $(LCM_FILES)
	@rm -rf $(B)/java && mkdir -p $(B)/java/src $(B)/java/classes
	lcm-gen -j --jpath $(B)/java/src $(LCM_FILES)
	javac -nowarn -cp /usr/share/java/lcm.jar -d $(B)/java/classes $(B)/java/src/marie/*.java
	jar cf $@ -C $(B)/java/classes .
EXTRA_TARGETS += $(LCM_JAR)

# Python: lcm-gen's classes under the namespace package lcmtypes (lcmtypes.marie: the name marie
# is the component package's, python/marie), with the descriptors python/marie checks payloads by.
PY_TYPES := $(B)/python/lcmtypes/marie/_typeinfo.py
$(PY_TYPES): $(LCM_FILES) lcmtypes/typeinfo_gen.py
	@rm -rf $(B)/python/lcmtypes/marie && mkdir -p $(B)/python
	lcm-gen -p --ppath $(B)/python --package-prefix lcmtypes $(LCM_FILES)
	@rm -f $(B)/python/lcmtypes/__init__.py
	python3 lcmtypes/typeinfo_gen.py py $@ $(LCM_FILES)
EXTRA_TARGETS += $(PY_TYPES)
