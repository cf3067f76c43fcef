# adapters/ros2: marie-ros2, the ROS 2 bridge on Cyclone DDS (docs/ros2.md). The ROS 2 messages'
# IDL is generated from their field lists (ros2_msgs.txt), then idlc makes their C types: without
# XTypes type information (-t), as rmw_cyclonedds registers them, so endpoints match by type name.
include adapters/common/adapters.mk
ROS2_GEN := $(B)/gen/ros2
$(ROS2_GEN)/ros2_types.idl: adapters/ros2/ros2_msgs.txt adapters/ros2/ros2_idl_gen.py
	@mkdir -p $(@D)
	python3 adapters/ros2/ros2_idl_gen.py $< $@
$(ROS2_GEN)/ros2_types.h: $(ROS2_GEN)/ros2_types.idl
	cd $(ROS2_GEN) && idlc -t ros2_types.idl
$(ROS2_GEN)/ros2_types.c: $(ROS2_GEN)/ros2_types.h ;
GEN_HEADERS += $(ROS2_GEN)/ros2_types.h
$(B)/obj/gen/ros2/ros2_types.o: $(ROS2_GEN)/ros2_types.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c -o $@ $<
CPPFLAGS += -I$(ROS2_GEN)
ROS2_OBJS := $(B)/obj/adapters/ros2/ros2_conv.o $(B)/obj/adapters/ros2/ros2_dds.o \
             $(B)/obj/adapters/ros2/ros2_table.o $(B)/obj/gen/ros2/ros2_types.o
$(B)/lib/libmarie_ros2.a: $(ROS2_OBJS)
	@mkdir -p $(@D)
	@rm -f $@
	$(AR) rcs $@ $^
ROS2_LIB := $(B)/lib/libmarie_ros2.a
ROS2_LIBS := $(ROS2_LIB) -lddsc
$(eval $(call marie_program,marie-ros2,adapters/ros2/ros2_main.c,$(ROS2_LIBS) $(ADAPT_COMMON)))
ITESTS += tests/ros2/test_ros2_system.sh
# Bytes from DDS through Cyclone's CDR check and the bridge's conversions (seeds: CDR written by
# the PyPI cyclonedds binding). The libFuzzer build compiles the conversions and types itself.
$(eval $(call marie_fuzz,ros2_cdr,tests/ros2/fuzz_ros2_cdr.c,$(ROS2_LIBS)))
FUZZ_ros2_cdr_SOURCES += adapters/ros2/ros2_conv.c $(ROS2_GEN)/ros2_types.c
FUZZ_ros2_cdr_LIBS := -lddsc
ITESTS += tests/ros2/test_ros2_bad_input.sh
$(eval $(call marie_test,test_ros2_conv,tests/ros2/test_ros2_conv.c tests/proc.c,$(ROS2_LIBS)))
$(eval $(call marie_bench,bench_ros2,bench/bench_ros2.c tests/proc.c,$(ROS2_LIBS)))
