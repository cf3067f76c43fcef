# bench: benchmarks that span several components.
# bench_pipeline starts the chain as marie-am does (managers/spawn.c; that module.mk comes later,
# hence the library's path rather than MANAGERS_LIB).
$(eval $(call marie_bench,bench_pipeline,bench/bench_pipeline.c tests/proc.c,$(B)/lib/libmarie_managers.a))
BENCHES += bench/bench_demo.sh bench/bench_scale.sh
$(eval $(call marie_bench,bench_config,bench/bench_config.c))
$(eval $(call marie_bench,bench_shm,bench/bench_shm.c))
$(eval $(call marie_bench,bench_rtt,bench/bench_rtt.c tests/proc.c))
$(eval $(call marie_bench,bench_send,bench/bench_send.c))
