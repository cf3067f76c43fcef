# tools/eval: marie-eval, random-goal navigation runs over the evaluation worlds and any map_server
# map (make bench-full: bench_eval).
$(eval $(call marie_program,marie-eval,tools/eval/eval_main.c tools/eval/eval_world.c tools/eval/eval_run.c,$(MAP_LIB)))
# The evaluation worlds are made at build time from sim/mkworld.py, not kept in git.
EVAL_WORLDS := $(B)/worlds/eval/office.yaml
$(EVAL_WORLDS): sim/mkworld.py
	@mkdir -p $(@D)
	python3 sim/mkworld.py --eval $(@D)
EXTRA_TARGETS += $(EVAL_WORLDS)
$(eval $(call marie_bench_full,bench_eval,bench/bench_eval.c,))
$(B)/bench/bench_eval: | $(B)/bin/marie-eval $(EVAL_WORLDS) $(B)/bin/marie-sim $(B)/bin/marie-odometry \
    $(B)/bin/marie-localizer $(B)/bin/marie-planner $(B)/bin/marie-behaviours
