/* audio: the simulator's microphone array: sound sources in the world (speech read from WAVE
 * files, white noise, a fan), propagation delay, 1/r attenuation, first-order wall
 * reflections and a diffuse noise field, rendered as 16-bit blocks for marie.audio_frame_t. */
#ifndef MARIE_SIM_AUDIO_H
#define MARIE_SIM_AUDIO_H
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hw/audio/micarray.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SIM_AUDIO_MAX_SOURCES 8
#define SIM_AUDIO_SPEED_OF_SOUND 343.0

typedef enum { SIM_SOUND_SPEECH, SIM_SOUND_NOISE, SIM_SOUND_FAN } sim_sound_kind_t;

/* One source of the scene. Positions are in the map frame, m; times in sim s. */
typedef struct {
    sim_sound_kind_t kind;
    double x, y, z;             /* where it is at `start` */
    double vx, vy;              /* m/s while it plays: a walking person */
    double start, stop;         /* plays in [start, stop); stop < 0: until its file ends (speech) or forever */
    double every;               /* speech: say it again every this many s (0: once) */
    double level;               /* RMS of the sound at 1 m, full scale = 1 */
    char file[256];             /* speech: 16-bit mono WAVE at the array's rate */
} sim_sound_t;

/* The whole scene: sources, the diffuse noise and the walls. */
typedef struct {
    int n;
    sim_sound_t src[SIM_AUDIO_MAX_SOURCES];
    double snr_db;              /* loudest source's direct sound over the diffuse noise at the start pose; >= 200: no noise */
    double reflect;             /* amplitude reflection coefficient of the walls, 0: anechoic */
} sim_audio_scene_t;

/* Parses the `audio` parameter: items separated by ';', each a kind and key=value words:
 *   speech file=F x= y= [z=1.5] [vx= vy=] [start=0] [stop=-1] [every=0] [level=0.05]
 *   noise|fan x= y= ...      diffuse snr=DB      walls reflect=B
 * An empty text is an empty scene. 0, or -1 with errno EINVAL and a reason in why. */
int sim_audio_scene_parse(const char *text, sim_audio_scene_t *out, char *why, size_t whylen);

typedef struct {
    int rate;                   /* Hz */
    int block;                  /* samples per channel and block */
    micarray_t mics;            /* robot frame */
    uint64_t seed;
    double start_pose[3];       /* where the snr is measured */
} sim_audio_cfg_t;

typedef struct sim_audio sim_audio_t;

/* map (may be NULL: no walls) is copied. Speech files are loaded here. NULL with errno and
 * a reason in why. */
sim_audio_t *sim_audio_create(const sim_audio_cfg_t *cfg, const sim_audio_scene_t *scene,
                              const occmap_t *map, char *why, size_t whylen);
void sim_audio_destroy(sim_audio_t *a);             /* NULL is a no-op */

/* Renders the block whose first sample is at t0_us, heard by the array of a robot at `pose`
 * (x, y, theta in the map frame), into out[nmics * block] (interleaved). Returns the number
 * of samples clipped to the int16 range. */
long sim_audio_render(sim_audio_t *a, int64_t t0_us, const double pose[3], int16_t *out);

/* Same, as floats (full scale 1), unclipped: what tests compare against. */
void sim_audio_render_float(sim_audio_t *a, int64_t t0_us, const double pose[3], float *out);

/* Which parts are rendered: bit i for source i, and the diffuse noise (tests measure each
 * part's share of a mixture this way). Everything by default. */
void sim_audio_set_mask(sim_audio_t *a, unsigned sources, bool diffuse);

/* Where source i is at t (map frame), and whether it sounds then. */
bool sim_audio_source_at(const sim_audio_t *a, int i, double t, double xyz[3]);

int sim_audio_channels(const sim_audio_t *a);

#ifdef __cplusplus
}
#endif
#endif
