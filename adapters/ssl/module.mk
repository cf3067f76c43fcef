# adapters/ssl: marie-ssl, sound source localization (SRP-PHAT), tracking and separation.
SSL_LIBS := $(B)/lib/libssl.a $(B)/lib/libmarie_audio.a -lfftw3f
# The tests render scenes with the simulator's array (sim/module.mk), with Festival's phrases.
SSL_TEST_LIBS := $(SSL_LIBS) $(B)/lib/libmariesim_audio.a $(B)/lib/libmarie_audio.a $(B)/lib/libmarie_map.a
$(eval $(call marie_lib,ssl,adapters/ssl/ssl_srp.c adapters/ssl/ssl_track.c adapters/ssl/ssl_sep.c adapters/ssl/ssl.c))
$(eval $(call marie_test,test_ssl,tests/audio/test_ssl.c tests/audio/audio_scene_util.c,$(SSL_TEST_LIBS)))
$(B)/tests/test_ssl: | $(B)/share/sounds/phrases.stamp
$(eval $(call marie_program,marie-ssl,adapters/ssl/ssl_main.c,$(SSL_LIBS)))
$(eval $(call marie_test,test_ssl_process,tests/audio/test_ssl_process.c tests/proc.c,))
$(B)/tests/test_ssl_process: | $(B)/bin/marie-sim $(B)/bin/marie-ssl $(B)/share/sounds/phrases.stamp
$(eval $(call marie_bench,bench_ssl,bench/bench_ssl.c tests/audio/audio_scene_util.c,$(SSL_TEST_LIBS)))
$(B)/bench/bench_ssl: | $(B)/share/sounds/phrases.stamp
