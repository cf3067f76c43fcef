# tools/types: marie-types-gen, which makes a user's .lcm files first-class marie types. It finds
# typeinfo_gen.py and marie's own .lcm files in <bin>/../share/marie, in the build tree as installed.
TYPES_SHARE := $(B)/share/marie
TYPES_SHARE_FILES := $(TYPES_SHARE)/typeinfo_gen.py $(patsubst lcmtypes/%,$(TYPES_SHARE)/lcmtypes/%,$(LCM_FILES))
$(B)/bin/marie-types-gen: tools/types/marie-types-gen $(TYPES_SHARE_FILES)
	@mkdir -p $(@D)
	cp $< $@ && chmod 755 $@
$(TYPES_SHARE)/typeinfo_gen.py: lcmtypes/typeinfo_gen.py
	@mkdir -p $(@D)
	cp $< $@
$(TYPES_SHARE)/lcmtypes/%.lcm: lcmtypes/%.lcm
	@mkdir -p $(@D)
	cp $< $@
EXTRA_TARGETS += $(B)/bin/marie-types-gen
INSTALL_EXTRA += install -m 755 $(B)/bin/marie-types-gen $(DESTDIR)$(PREFIX)/bin/ && \
    install -d $(DESTDIR)$(PREFIX)/share/marie/lcmtypes && \
    install -m 644 $(TYPES_SHARE)/typeinfo_gen.py $(DESTDIR)$(PREFIX)/share/marie/ && \
    install -m 644 $(LCM_FILES) $(DESTDIR)$(PREFIX)/share/marie/lcmtypes/;
ITESTS += tests/tools/test_user_types.sh
