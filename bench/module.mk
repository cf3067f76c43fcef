# bench: benchmarks that span several components.
$(eval $(call marie_bench,bench_pipeline,bench/bench_pipeline.c tests/proc.c))
BENCHES += bench/bench_demo.sh bench/bench_scale.sh
$(eval $(call marie_bench,bench_config,bench/bench_config.c))
$(eval $(call marie_bench,bench_shm,bench/bench_shm.c))
$(eval $(call marie_bench,bench_rtt,bench/bench_rtt.c tests/proc.c))
$(eval $(call marie_bench,bench_send,bench/bench_send.c))
