/* audio_port: marie-sim's microphone array on the bus: reads the `audio`, `mics`,
 * `audio_rate` and `audio_block` parameters, renders a block whenever simulated time has
 * passed one, and publishes it as marie.audio_frame_t on the `audio` port. */
#ifndef MARIE_SIM_AUDIO_PORT_H
#define MARIE_SIM_AUDIO_PORT_H
#include <stdint.h>

#include "core/component.h"
#include "hw/audio/micarray.h"
#include "map/occmap.h"

typedef struct sim_audio_port sim_audio_port_t;

/* *out is NULL when the `audio` parameter is empty (no array). 0, or -1 after
 * marie_component_fail_reason(). */
int sim_audio_port_create(marie_component_t *c, const occmap_t *map, const double start_pose[3],
                          uint64_t seed, int64_t start_utime, sim_audio_port_t **out);
void sim_audio_port_destroy(sim_audio_port_t *p);          /* NULL is a no-op */

/* After each physics step: publishes every block that ended by now_us (none when p is NULL). */
void sim_audio_port_step(sim_audio_port_t *p, int64_t now_us, const double pose[3]);

#endif
