# adapters/dialogue: marie-dialogue, spoken commands to goals, stops and answers.
$(eval $(call marie_lib,dialogue,adapters/dialogue/dialogue.c adapters/dialogue/speaker_dir.c))
$(eval $(call marie_program,marie-dialogue,adapters/dialogue/dialogue_main.c,$(B)/lib/libdialogue.a))
$(eval $(call marie_test,test_dialogue,tests/audio/test_dialogue.c,$(B)/lib/libdialogue.a))
$(eval $(call marie_fuzz,dialogue_places,tests/audio/fuzz_dialogue_places.c adapters/dialogue/dialogue.c,))
# The spoken-command chain end to end: array -> ssl -> asr -> dialogue -> tts, as processes.
$(eval $(call marie_test,test_spoken_command,tests/audio/test_spoken_command.c tests/proc.c,))
$(B)/tests/test_spoken_command: | $(B)/bin/marie-sim $(B)/bin/marie-ssl $(B)/bin/marie-asr $(B)/bin/marie-dialogue \
    $(B)/bin/marie-tts $(B)/share/sounds/phrases.stamp
