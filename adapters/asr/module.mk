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
