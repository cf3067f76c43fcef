# hw/audio: microphone array and loudspeaker: WAVE files, array geometry, ALSA driver (marie-audio).
AUDIO_LIB := $(B)/lib/libmarie_audio.a
$(eval $(call marie_lib,marie_audio,hw/audio/wav.c hw/audio/micarray.c hw/audio/blocker.c))
$(eval $(call marie_test,test_audio_formats,tests/audio/test_audio_formats.c,$(AUDIO_LIB)))
$(eval $(call marie_fuzz,audio_wav,tests/audio/fuzz_audio_wav.c hw/audio/wav.c hw/audio/micarray.c,))
$(eval $(call marie_program,marie-audio,hw/audio/audio_main.c,$(AUDIO_LIB) -lasound))
$(eval $(call marie_test,test_audio_alsa,tests/audio/test_audio_alsa.c tests/proc.c,))
$(B)/tests/test_audio_alsa: | $(B)/bin/marie-audio
