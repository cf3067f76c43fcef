/* audio_port: marie-sim's microphone array on the bus (see audio_port.h). */
#include "sim/audio_port.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "sim/audio.h"
#include "sim/sim_opts.h"

struct sim_audio_port {
    marie_component_t *c;
    marie_port_t *port;
    sim_audio_t *audio;
    int rate, block, nmics;
    int64_t next_utime;         /* first sample of the next block */
    int64_t seq;
    int16_t *buf;
};

int sim_audio_port_create(marie_component_t *c, const occmap_t *map, const double start_pose[3],
                          uint64_t seed, int64_t start_utime, sim_audio_port_t **out)
{
    *out = NULL;
    const char *scene_text = sim_opts(c)->audio;
    if (!scene_text || !*scene_text)
        return 0;
    char why[256] = "";
    const char *mwhy = NULL;
    sim_audio_scene_t scene;
    sim_audio_cfg_t cfg = { .rate = (int)sim_opts(c)->audio_rate,
                            .block = (int)sim_opts(c)->audio_block, .seed = seed };
    memcpy(cfg.start_pose, start_pose, sizeof(cfg.start_pose));
    if (sim_audio_scene_parse(scene_text, &scene, why, sizeof(why))) {
        marie_component_fail_reason(c, "audio: %s", why);
        return -1;
    }
    if (micarray_parse(sim_opts(c)->mics, &cfg.mics, &mwhy)) {
        marie_component_fail_reason(c, "mics: %s", mwhy);
        return -1;
    }
    sim_audio_port_t *p = calloc(1, sizeof(*p));
    if (!p || !(p->buf = malloc(sizeof(int16_t) * (size_t)(cfg.block > 0 ? cfg.block : 1) * (size_t)cfg.mics.n)) ||
        !(p->audio = sim_audio_create(&cfg, &scene, map, why, sizeof(why)))) {
        marie_component_fail_reason(c, "audio: %s", why[0] ? why : strerror(errno));
        sim_audio_port_destroy(p);
        return -1;
    }
    p->c = c;
    p->port = marie_port(c, "audio");
    p->rate = cfg.rate;
    p->block = cfg.block;
    p->nmics = cfg.mics.n;
    p->next_utime = start_utime;
    marie_info("audio: %d sources, %d microphones at %d Hz in blocks of %d", scene.n, cfg.mics.n, cfg.rate, cfg.block);
    *out = p;
    return 0;
}

void sim_audio_port_destroy(sim_audio_port_t *p)
{
    if (!p)
        return;
    sim_audio_destroy(p->audio);
    free(p->buf);
    free(p);
}

void sim_audio_port_step(sim_audio_port_t *p, int64_t now_us, const double pose[3])
{
    if (!p)
        return;
    for (;;) {
        /* Block k starts at next_utime; times are kept exact by counting samples. */
        int64_t end = p->next_utime + (int64_t)p->block * 1000000 / p->rate;
        if (end > now_us)
            return;
        long clipped = sim_audio_render(p->audio, p->next_utime, pose, p->buf);
        if (clipped > 0)
            marie_component_count(p->c, "audio_clipped", clipped);
        marie_audio_frame_t f = { .utime = p->next_utime, .seq = p->seq++, .device = "sim",
                                  .sample_rate = p->rate, .nchannels = (int16_t)p->nmics, .nsamples = p->block,
                                  .nvalues = p->block * p->nmics, .data = p->buf };
        marie_port_publish(p->port, &f);
        p->next_utime += (int64_t)p->block * 1000000 / p->rate;
    }
}
