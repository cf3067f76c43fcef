# proto: the managers' wire protocol as their clients see it (channels, order names, exit codes,
# signed orders): marie-am, the marie command line and the tools link it.
PROTO_LIB := $(B)/lib/libmarie_proto.a
$(eval $(call marie_lib,marie_proto,proto/am_proto.c))
