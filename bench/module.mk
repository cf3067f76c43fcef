# bench: benchmarks that span several components.
$(eval $(call marie_bench,bench_pipeline,bench/bench_pipeline.c tests/proc.c))
BENCHES += bench/bench_demo.sh
$(eval $(call marie_bench,bench_config,bench/bench_config.c))
$(eval $(call marie_bench,bench_shm,bench/bench_shm.c))
