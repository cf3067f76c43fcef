# adapters/xml_bridge: the typed XML <-> LCM bridge for peers that cannot link LCM.
# Type descriptors are generated from lcmtypes/*.lcm at build time (lcmtypes/typeinfo_gen.py).
# (The descriptor table itself is in libmarie: core/typeinfo.h.)
XB_GEN_DIR := $(B)/gen/xml_bridge
XB_STRUCTDUMP := $(XB_GEN_DIR)/xb_structdump.c
$(XB_STRUCTDUMP): $(LCM_FILES) lcmtypes/typeinfo_gen.py
	@mkdir -p $(@D)
	python3 lcmtypes/typeinfo_gen.py dump $@ $(LCM_FILES)

# The XML Schema of every type's fields, for peers (docs/xml-bridge.md).
XB_TYPES_XSD := $(XB_GEN_DIR)/xml-bridge-types.xsd
$(XB_TYPES_XSD): $(LCM_FILES) lcmtypes/typeinfo_gen.py
	@mkdir -p $(@D)
	python3 lcmtypes/typeinfo_gen.py xsd $@ $(LCM_FILES)
EXTRA_TARGETS += $(XB_TYPES_XSD)
INSTALL_EXTRA += install -d $(DESTDIR)$(PREFIX)/share/marie && install -m 644 docs/xml-bridge.xsd $(XB_TYPES_XSD) $(DESTDIR)$(PREFIX)/share/marie/;

# Pure codec and document parser (no libmarie): also what the fuzzer links.
XB_CODEC_SRCS := adapters/xml_bridge/xb_doc.c adapters/xml_bridge/xb_text.c adapters/xml_bridge/xb_codec.c
XB_SRCS := $(XB_CODEC_SRCS) adapters/xml_bridge/xb_server.c adapters/xml_bridge/xb_out.c \
           adapters/xml_bridge/xb_requests.c
$(eval $(call marie_lib,xml_bridge,$(XB_SRCS)))
XB_LIB := $(B)/lib/libxml_bridge.a

$(eval $(call marie_program,marie-xml-bridge,adapters/xml_bridge/xml_bridge_main.c,$(XB_LIB) -lexpat))

XB_TEST_SRCS := tests/xml_bridge/xb_canon.c $(XB_STRUCTDUMP)
$(eval $(call marie_test,test_xb_codec,tests/xml_bridge/test_xb_codec.c $(XB_TEST_SRCS),$(XB_LIB) -lexpat))
$(eval $(call marie_test,test_xb_server,tests/xml_bridge/test_xb_server.c $(XB_TEST_SRCS),$(XB_LIB) -lexpat))
$(eval $(call marie_fuzz,xml_bridge_doc,tests/xml_bridge/fuzz_xml_bridge_doc.c $(XB_CODEC_SRCS),-lexpat))
ITESTS += tests/xml_bridge/test_xml_peer.py tests/xml_bridge/test_xml_memory.py
$(eval $(call marie_bench,bench_xml_bridge,bench/bench_xml_bridge.c,$(XB_LIB) -lexpat))
