# tools/log: marie-log, behind `marie log import carmen` (a CARMEN laser log as an LCM log).
$(eval $(call marie_program,marie-log,tools/log/log_main.c tools/log/carmen.c,-lz))
$(eval $(call marie_test,test_carmen,tests/log/test_carmen.c tools/log/carmen.c,))
$(eval $(call marie_fuzz,carmen,tests/log/fuzz_carmen.c tools/log/carmen.c,))
