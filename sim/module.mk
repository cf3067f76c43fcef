# sim: marie-sim, the ODE simulator (channel and device modes), and its worlds.
ODE_LIBS := $(shell pkg-config --libs ode 2>/dev/null)
SIM_LIB := $(B)/lib/libmariesim.a $(MAP_LIB)

$(eval $(call marie_lib,mariesim,sim/walls.c sim/world.c))
# The microphone array (sim/audio.c) and its phrases, spoken once by Festival at build time.
SIM_AUDIO_LIB := $(B)/lib/libmariesim_audio.a $(B)/lib/libmarie_audio.a
$(eval $(call marie_lib,mariesim_audio,sim/audio.c sim/audio_port.c))

$(eval $(call marie_test,test_sim_world,tests/sim/test_sim_world.c,$(SIM_LIB) $(ODE_LIBS)))

# Device mode drives the hw/ emulators: virtual CiA 402 drives and gyro, virtual LMS200.
SIM_DEVICE_LIBS := $(B)/lib/libmarie_vdevices.a $(B)/lib/libmarie_drives.a $(B)/lib/libmarie_gyro.a \
    $(B)/lib/libmarie_canopen.a $(B)/lib/libmarie_can.a $(B)/lib/libmarie_lms200.a -lutil
$(eval $(call marie_program,marie-sim,sim/sim_main.c sim/devices.c sim/camera.c,$(SIM_LIB) $(SIM_AUDIO_LIB) $(SIM_DEVICE_LIBS) $(ODE_LIBS) $(CAMERA_LIBS)))

$(eval $(call marie_bench,bench_sim,bench/bench_sim.c,$(SIM_LIB) $(ODE_LIBS)))
$(B)/bench/bench_sim: | $(B)/bin/marie-sim

$(eval $(call marie_test,test_sim_channels,tests/sim/test_sim_channels.c tests/proc.c,))
# The device-mode case runs the real drivers against the simulator.
$(B)/tests/test_sim_channels: | $(B)/bin/marie-sim $(B)/bin/marie-drives $(B)/bin/marie-gyro $(B)/bin/marie-lms200


# The camera's cost (docs/vision.md): render time and real-time factor with and without it.
$(eval $(call marie_bench,bench_sim_camera,bench/bench_sim_camera.c sim/camera.c,$(SIM_LIB) $(ODE_LIBS) $(CAMERA_LIBS)))
$(B)/bench/bench_sim_camera: | $(B)/bin/marie-sim
$(eval $(call marie_test,test_sim_camera,tests/sim/test_sim_camera.c sim/camera.c,$(SIM_LIB) $(VISION_LIBS)))
$(B)/obj/tests/sim/test_sim_camera.o: CPPFLAGS += $(CAMERA_CV_CFLAGS)
# phrase_NN.wav: line NN of sim/sounds/phrases.txt in Festival's US English voice at 16 kHz.
SIM_PHRASES := $(shell seq -f '$(B)/share/sounds/phrase_%02g.wav' 1 $$(wc -l < sim/sounds/phrases.txt))
$(B)/share/sounds/phrase_%.wav: sim/sounds/phrases.txt
	@mkdir -p $(@D)
	@# text2wave with a Lisp heap of 1M cells, as marie-tts runs it: the same file, 3x faster (docs/audio.md)
	sed -n "$$(echo $* | sed 's/^0//')p" $< > $@.txt && \
	festival --heap 1000000 -b '(set! argv (list "-F" "16000" "-o" "$@" "$@.txt"))' /usr/bin/text2wave && rm -f $@.txt
EXTRA_TARGETS += $(SIM_PHRASES)
$(eval $(call marie_fuzz,audio_scene,tests/audio/fuzz_audio_scene.c sim/audio.c hw/audio/wav.c hw/audio/micarray.c map/occmap.c map/pgm.c map/occmap_load.c,))
$(B)/share/sounds/phrases.stamp: $(SIM_PHRASES)
	@touch $@
# Device mode as fast as the computer allows, with the real drivers on the sim clock.
$(eval $(call marie_test,test_sim_fast_devices,tests/sim/test_sim_fast_devices.c tests/proc.c,))
$(B)/tests/test_sim_fast_devices: | $(B)/bin/marie-sim $(B)/bin/marie-drives $(B)/bin/marie-gyro $(B)/bin/marie-lms200
# Its checks (no protocol timeout on either side of the emulated bus at speed 0) need the two
# cores: beside the parallel tests it failed now and then (a driver starved for a second of wall
# time), and beside the light tests too, so it runs last in make test, alone.
TESTS := $(filter-out $(B)/tests/test_sim_fast_devices,$(TESTS))
ALONE_TESTS += $(B)/tests/test_sim_fast_devices
EXTRA_TARGETS += $(B)/tests/test_sim_fast_devices
