# adapters/asr: marie-asr, command recognition with PocketSphinx on separated streams.
ASR_CFLAGS := $(shell pkg-config --cflags pocketsphinx 2>/dev/null)
ASR_LIBS := $(B)/lib/libasr.a $(shell pkg-config --libs pocketsphinx 2>/dev/null)
$(B)/obj/adapters/asr/%.o: CPPFLAGS += $(ASR_CFLAGS)
$(eval $(call marie_lib,asr,adapters/asr/asr.c adapters/asr/asr_vad.c))
$(eval $(call marie_program,marie-asr,adapters/asr/asr_main.c,$(ASR_LIBS)))
# The recognition test renders and separates with the simulator's array and marie-ssl's library.
$(eval $(call marie_test,test_asr,tests/audio/test_asr.c tests/audio/audio_scene_util.c,$(ASR_LIBS) \
    $(B)/lib/libssl.a $(B)/lib/libmariesim_audio.a $(B)/lib/libmarie_audio.a $(B)/lib/libmarie_map.a -lfftw3f))
$(B)/tests/test_asr: | $(B)/share/sounds/phrases.stamp
# Voices that are not Festival's (espeak-ng) and rooms rendered by pyroomacoustics, in a venv
# made by scripts/room-venv.sh: tests/audio/room_scene.py.
$(B)/share/voices/stamp: tests/audio/room_scene.py scripts/room-venv.sh
	@mkdir -p $(@D)
	B=$(B) scripts/room-venv.sh >/dev/null && $(B)/room/bin/python tests/audio/room_scene.py voices $(@D) && touch $@
$(B)/tests/test_asr: | $(B)/share/voices/stamp
# The continuous scene of the test: 40 utterances, RT60 0.3 s, every one 5 dB over a fan.
$(B)/share/rooms/test_rt30_snr5.wav: $(B)/share/voices/stamp tests/data/speech/transcripts.tsv
	@mkdir -p $(@D)
	$(B)/room/bin/python tests/audio/room_scene.py scene --rt60 0.3 --snr 5 --utterances 40 --seed 45 \
	    $(B)/share/voices $@ $(@:.wav=.tsv)
ASR_EVAL_LIBS := $(ASR_LIBS) $(B)/lib/libssl.a $(B)/lib/libmarie_audio.a -lfftw3f
$(eval $(call marie_test,test_asr_continuous,tests/audio/test_asr_continuous.c tests/audio/asr_eval.c,$(ASR_EVAL_LIBS)))
$(B)/tests/test_asr_continuous: | $(B)/share/rooms/test_rt30_snr5.wav
$(eval $(call marie_bench,bench_asr,bench/bench_asr.c tests/audio/asr_eval.c,$(ASR_EVAL_LIBS)))
$(eval $(call marie_bench_full,bench_asr_full,bench/bench_asr.c tests/audio/asr_eval.c,$(ASR_EVAL_LIBS)))
$(B)/obj/bench/bench_asr.o: CPPFLAGS += $(ASR_CFLAGS)
$(B)/bench/bench_asr $(B)/bench/bench_asr_full: | $(B)/share/voices/stamp
