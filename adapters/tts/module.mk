# adapters/tts: marie-tts, Festival's voice (text2wave in a child process) published on the bus.
$(eval $(call marie_program,marie-tts,adapters/tts/tts_main.c adapters/tts/tts_child.c,$(B)/lib/libmarie_audio.a))
$(eval $(call marie_test,test_tts_process,tests/audio/test_tts_process.c tests/proc.c adapters/tts/tts_child.c,$(B)/lib/libmarie_audio.a))
$(B)/tests/test_tts_process: | $(B)/bin/marie-tts
