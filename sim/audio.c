/* audio: the simulator's microphone array (see audio.h; the model is in docs/audio.md). */
#include "sim/audio.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/clear.h"
#include "core/log.h"
#include "hw/audio/wav.h"
#include "sim/rng.h"

#define TAPS 16                 /* windowed-sinc fractional delay: flat to ~0.8 of Nyquist */
#define PHASES 512
#define NDIFFUSE 64             /* plane waves making up the diffuse field */
#define LOOP_S 4.0              /* generated noises repeat after this long */
#define MAX_PATHS 5             /* direct + one image per wall around the robot */

typedef struct {
    sim_sound_t s;
    float *sig;
    size_t len;
    long period;                /* speech with `every`: samples between repetitions */
} source_t;

struct sim_audio {
    sim_audio_cfg_t cfg;
    int nsrc;
    source_t src[SIM_AUDIO_MAX_SOURCES];
    double reflect, noise_rms;
    float *diffuse[NDIFFUSE];
    size_t dlen;
    long idelay[NDIFFUSE][MICARRAY_MAX];    /* samples, >= 0 */
    float table[PHASES][TAPS];
    occmap_t *map;
    double prev_pose[3];
    bool have_prev;
    unsigned mask;
    bool diffuse_on;
    float *acc;
};

/* ---- scene text ------------------------------------------------------------------------ */

static int set_number(double *dst, const char *val, double lo, double hi)
{
    char *end;
    errno = 0;
    double v = strtod(val, &end);
    if (end == val || *end || errno || !isfinite(v) || v < lo || v > hi)
        return -1;
    *dst = v;
    return 0;
}

/* One key=value of a source; -1 when the key is unknown or the value bad. */
static int source_key(sim_sound_t *s, const char *key, const char *val)
{
    static const struct { const char *key; size_t off; double lo, hi; } keys[] = {
        { "x", offsetof(sim_sound_t, x), -1e4, 1e4 }, { "y", offsetof(sim_sound_t, y), -1e4, 1e4 },
        { "z", offsetof(sim_sound_t, z), -100, 100 }, { "vx", offsetof(sim_sound_t, vx), -10, 10 },
        { "vy", offsetof(sim_sound_t, vy), -10, 10 }, { "start", offsetof(sim_sound_t, start), 0, 1e6 },
        { "stop", offsetof(sim_sound_t, stop), -1, 1e6 }, { "every", offsetof(sim_sound_t, every), 0, 1e4 },
        { "level", offsetof(sim_sound_t, level), 0, 10 },
    };
    if (!strcmp(key, "file")) {
        if (strlen(val) >= sizeof(s->file) || !*val)
            return -1;
        strcpy(s->file, val);
        return 0;
    }
    for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
        if (!strcmp(key, keys[i].key))
            return set_number((double *)((char *)s + keys[i].off), val, keys[i].lo, keys[i].hi);
    return -1;
}

static int scene_item(sim_audio_scene_t *sc, char *item, char *why, size_t whylen)
{
    char *save = NULL, *word = strtok_r(item, " \t\n", &save);
    if (!word)
        return 0;
    sim_sound_t s = { .z = 1.5, .stop = -1, .level = 0.05 };
    int kind = !strcmp(word, "speech") ? SIM_SOUND_SPEECH : !strcmp(word, "noise") ? SIM_SOUND_NOISE
             : !strcmp(word, "fan") ? SIM_SOUND_FAN : !strcmp(word, "diffuse") ? 10
             : !strcmp(word, "walls") ? 11 : -1;
    if (kind < 0)
        return marie_fail_why(why, whylen, "unknown item '%.40s' (speech, noise, fan, diffuse, walls)", word);
    if (kind < 10 && sc->n == SIM_AUDIO_MAX_SOURCES)
        return marie_fail_why(why, whylen, "more than %d sources", SIM_AUDIO_MAX_SOURCES);
    s.kind = (sim_sound_kind_t)(kind < 10 ? kind : 0);
    while ((word = strtok_r(NULL, " \t\n", &save))) {
        char *eq = strchr(word, '=');
        if (!eq)
            return marie_fail_why(why, whylen, "expected key=value, got '%.40s'", word);
        *eq = 0;
        int bad = kind == 10 ? (strcmp(word, "snr") || set_number(&sc->snr_db, eq + 1, -40, 1000))
                : kind == 11 ? (strcmp(word, "reflect") || set_number(&sc->reflect, eq + 1, 0, 0.99))
                : source_key(&s, word, eq + 1);
        if (bad)
            return marie_fail_why(why, whylen, "bad key or value '%.40s=%.40s'", word, eq + 1);
    }
    if (kind == SIM_SOUND_SPEECH && !s.file[0])
        return marie_fail_why(why, whylen, "speech needs file=");
    if (kind < 10)
        sc->src[sc->n++] = s;
    return 0;
}

int sim_audio_scene_parse(const char *text, sim_audio_scene_t *out, char *why, size_t whylen)
{
    memset(out, 0, sizeof(*out));
    out->snr_db = 1000;
    if (!text)
        return 0;
    size_t len = strlen(text);
    if (len > 8192)
        return marie_fail_why(why, whylen, "scene longer than 8192 characters");
    char *copy = strdup(text);
    if (!copy)
        return -1;
    char *save = NULL;
    int rc = 0;
    for (char *item = strtok_r(copy, ";", &save); item && !rc; item = strtok_r(NULL, ";", &save))
        rc = scene_item(out, item, why, whylen);
    free(copy);
    return rc;
}

/* ---- signals --------------------------------------------------------------------------- */

static void normalize(float *x, size_t n, double rms)
{
    double e = 0;
    for (size_t i = 0; i < n; i++)
        e += (double)x[i] * x[i];
    double g = e > 0 ? rms / sqrt(e / (double)n) : 0;
    for (size_t i = 0; i < n; i++)
        x[i] = (float)(x[i] * g);
}

/* Speech is scaled by the RMS of its voiced part: leading and trailing silence of the file
 * must not make a phrase louder. */
static void normalize_active(float *x, size_t n, double rms)
{
    double peak = 0, e = 0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        peak = fmax(peak, fabs(x[i]));
    for (size_t i = 0; i < n; i++)
        if (fabs(x[i]) > 0.05 * peak) {
            e += (double)x[i] * x[i];
            k++;
        }
    double g = k ? rms / sqrt(e / (double)k) : 0;
    for (size_t i = 0; i < n; i++)
        x[i] = (float)(x[i] * g);
}

/* A fan: broadband noise below ~1 kHz and the hum of its blades (100 Hz and harmonics). */
static void make_fan(float *x, size_t n, int rate, sim_rng_t *r)
{
    double lp = 0, a = exp(-2 * M_PI * 1000.0 / rate);
    for (size_t i = 0; i < n; i++) {
        lp = a * lp + (1 - a) * sim_rng_gauss(r);
        double t = (double)i / rate;
        x[i] = (float)(lp * 3 + 0.3 * sin(2 * M_PI * 100 * t) + 0.2 * sin(2 * M_PI * 200 * t + 1)
                       + 0.1 * sin(2 * M_PI * 300 * t + 2));
    }
}

static int load_source(sim_audio_t *a, source_t *s, sim_rng_t *r, char *why, size_t whylen)
{
    int rate = a->cfg.rate;
    if (s->s.kind == SIM_SOUND_SPEECH) {
        int frate = 0;
        s->sig = wav_load_mono(s->s.file, &s->len, &frate);
        if (!s->sig)
            return marie_fail_why(why, whylen, "%s: %s", s->s.file, strerror(errno));
        if (frate != rate) {
            MARIE_CLEAR(s->sig, free);
            return marie_fail_why(why, whylen, "%s: %d Hz, the array runs at %d Hz", s->s.file, frate, rate);
        }
        normalize_active(s->sig, s->len, s->s.level);
        s->period = s->s.every > 0 ? lround(s->s.every * rate) : 0;
        return 0;
    }
    s->len = (size_t)(LOOP_S * rate);
    if (!(s->sig = malloc(s->len * sizeof(float))))
        return -1;
    if (s->s.kind == SIM_SOUND_FAN)
        make_fan(s->sig, s->len, rate, r);
    else
        for (size_t i = 0; i < s->len; i++)
            s->sig[i] = (float)sim_rng_gauss(r);
    normalize(s->sig, s->len, s->s.level);
    return 0;
}

/* Sample u (samples since the source's start) of source s; 0 where it is silent. */
static inline float source_sample(const source_t *s, long u, long stop_u)
{
    if (u < 0 || (stop_u >= 0 && u >= stop_u))
        return 0;
    if (s->s.kind != SIM_SOUND_SPEECH)
        return s->sig[u % (long)s->len];
    if (s->period > 0)
        u %= s->period;
    return u < (long)s->len ? s->sig[u] : 0;
}

static void make_table(sim_audio_t *a)
{
    for (int p = 0; p < PHASES; p++) {
        double f = (double)p / PHASES, sum = 0, h[TAPS];
        for (int j = 0; j < TAPS; j++) {
            double x = (j - (TAPS / 2 - 1)) - f;
            double sinc = fabs(x) < 1e-9 ? 1 : sin(M_PI * x) / (M_PI * x);
            double w = 0.42 + 0.5 * cos(M_PI * x / (TAPS / 2)) + 0.08 * cos(2 * M_PI * x / (TAPS / 2));
            h[j] = sinc * w;
            sum += h[j];
        }
        for (int j = 0; j < TAPS; j++)
            a->table[p][j] = (float)(h[j] / sum);
    }
}

/* ---- geometry -------------------------------------------------------------------------- */

bool sim_audio_source_at(const sim_audio_t *a, int i, double t, double xyz[3])
{
    const sim_sound_t *s = &a->src[i].s;
    double end = s->stop >= 0 ? fmin(t, s->stop) : t;
    double dt = fmax(0, end - s->start);
    xyz[0] = s->x + s->vx * dt;
    xyz[1] = s->y + s->vy * dt;
    xyz[2] = s->z;
    return t >= s->start && (s->stop < 0 || t < s->stop);
}

static void mic_world(const sim_audio_t *a, const double pose[3], int m, double out[3])
{
    const double *p = a->cfg.mics.pos[m];
    double c = cos(pose[2]), s = sin(pose[2]);
    out[0] = pose[0] + c * p[0] - s * p[1];
    out[1] = pose[1] + s * p[0] + c * p[1];
    out[2] = p[2];
}

/* The source and its images in the walls found around the robot along the map's axes
 * (a shoebox around the robot: good in rooms, rough in corridors); gain per path. */
static int paths(const sim_audio_t *a, const double pose[3], const double src[3],
                 double img[MAX_PATHS][3], double gain[MAX_PATHS])
{
    int n = 0;
    memcpy(img[n], src, sizeof(double) * 3);
    gain[n++] = 1;
    if (!a->map || a->reflect <= 0)
        return n;
    for (int k = 0; k < 4; k++) {
        double ang = k * M_PI / 2, d = occmap_raycast(a->map, pose[0], pose[1], ang, 30.0);
        if (d >= 30.0)
            continue;
        int axis = k % 2;                      /* 0: a wall across x, 1: across y */
        double plane = pose[axis] + (k < 2 ? d : -d);
        if ((src[axis] - plane) * (pose[axis] - plane) <= 0)
            continue;                          /* the source is beyond that wall */
        memcpy(img[n], src, sizeof(double) * 3);
        img[n][axis] = 2 * plane - src[axis];
        gain[n++] = a->reflect;
    }
    return n;
}

static double dist3(const double a[3], const double b[3])
{
    return fmax(0.1, sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])));
}

/* ---- rendering ------------------------------------------------------------------------- */

static inline float interp(const sim_audio_t *a, const source_t *s, double p, long stop_u)
{
    long i = (long)floor(p);
    int ph = (int)((p - (double)i) * PHASES);
    if (ph >= PHASES)
        ph = PHASES - 1;
    const float *h = a->table[ph];
    float v = 0;
    long base = i - (TAPS / 2 - 1);
    for (int j = 0; j < TAPS; j++)
        v += h[j] * source_sample(s, base + j, stop_u);
    return v;
}

/* One source over one block: each path's delay and gain move linearly from the previous
 * pose (block start) to this one (block end), so a turning robot makes no clicks. */
static void render_source(sim_audio_t *a, int i, int64_t t0_us, const double pose[3])
{
    const source_t *s = &a->src[i];
    int B = a->cfg.block, M = a->cfg.mics.n, rate = a->cfg.rate;
    double t0 = t0_us / 1e6, t1 = t0 + (double)B / rate;
    double span = (s->s.stop >= 0 ? s->s.stop : 1e9) + 0.2;
    if (t1 < s->s.start || t0 > span)
        return;
    double p0[3], p1[3], img0[MAX_PATHS][3], img1[MAX_PATHS][3], g0[MAX_PATHS], g1[MAX_PATHS];
    sim_audio_source_at(a, i, t0, p0);
    sim_audio_source_at(a, i, t1, p1);
    int n0 = paths(a, a->prev_pose, p0, img0, g0), n1 = paths(a, pose, p1, img1, g1);
    int n = n0 < n1 ? n0 : n1;
    long stop_u = s->s.stop >= 0 ? lround((s->s.stop - s->s.start) * rate) : -1;
    double u0 = (t0 - s->s.start) * rate;
    for (int m = 0; m < M; m++) {
        double ma[3], mb[3];
        mic_world(a, a->prev_pose, m, ma);
        mic_world(a, pose, m, mb);
        for (int k = 0; k < n; k++) {
            double ra = dist3(img0[k], ma), rb = dist3(img1[k], mb);
            double da = ra / SIM_AUDIO_SPEED_OF_SOUND * rate, db = rb / SIM_AUDIO_SPEED_OF_SOUND * rate;
            double ga = g0[k] / ra, gb = g1[k] / rb;
            float *out = a->acc + m;
            for (int j = 0; j < B; j++) {
                double f = (double)j / B;
                out[(size_t)j * M] += (float)((ga + (gb - ga) * f) * interp(a, s, u0 + j - (da + (db - da) * f), stop_u));
            }
        }
    }
}

/* Whole-sample delays: a plane wave's direction is arbitrary anyway, and this keeps 64 of
 * them cheap. */
static void render_diffuse(sim_audio_t *a, int64_t t0_us)
{
    int B = a->cfg.block, M = a->cfg.mics.n;
    long u0 = (long)(t0_us * a->cfg.rate / 1000000);
    for (int d = 0; d < NDIFFUSE; d++) {
        const float *x = a->diffuse[d];
        long len = (long)a->dlen;
        for (int m = 0; m < M; m++) {
            long base = u0 - a->idelay[d][m];
            for (int j = 0; j < B; j++) {
                long u = (base + j) % len;
                a->acc[(size_t)j * M + m] += x[u < 0 ? u + len : u];
            }
        }
    }
}

void sim_audio_render_float(sim_audio_t *a, int64_t t0_us, const double pose[3], float *out)
{
    if (!a->have_prev) {
        memcpy(a->prev_pose, pose, sizeof(a->prev_pose));
        a->have_prev = true;
    }
    a->acc = out;
    memset(out, 0, sizeof(float) * (size_t)a->cfg.block * (size_t)a->cfg.mics.n);
    for (int i = 0; i < a->nsrc; i++)
        if (a->mask & (1u << i))
            render_source(a, i, t0_us, pose);
    if (a->diffuse_on && a->noise_rms > 0)
        render_diffuse(a, t0_us);
    memcpy(a->prev_pose, pose, sizeof(a->prev_pose));
    a->acc = NULL;
}

long sim_audio_render(sim_audio_t *a, int64_t t0_us, const double pose[3], int16_t *out)
{
    size_t n = (size_t)a->cfg.block * (size_t)a->cfg.mics.n;
    float *f = malloc(n * sizeof(float));
    if (!f)
        return -1;
    sim_audio_render_float(a, t0_us, pose, f);
    long clipped = 0;
    for (size_t i = 0; i < n; i++) {
        double v = f[i] * 32768.0;
        if (v > 32767 || v < -32768)
            clipped++;
        out[i] = (int16_t)lrint(fmax(-32768, fmin(32767, v)));
    }
    free(f);
    return clipped;
}

void sim_audio_set_mask(sim_audio_t *a, unsigned sources, bool diffuse)
{
    a->mask = sources;
    a->diffuse_on = diffuse;
}

int sim_audio_channels(const sim_audio_t *a)
{
    return a->cfg.mics.n;
}

/* ---- life ------------------------------------------------------------------------------ */

/* The diffuse field: NDIFFUSE uncorrelated plane waves from directions spread evenly over the
 * sphere (a Fibonacci lattice); each carries 1/NDIFFUSE of the noise power. */
static int make_diffuse(sim_audio_t *a, sim_rng_t *r)
{
    const micarray_t *mics = &a->cfg.mics;
    a->dlen = (size_t)(LOOP_S * a->cfg.rate);
    double margin = micarray_aperture(mics) / SIM_AUDIO_SPEED_OF_SOUND * a->cfg.rate + TAPS;
    for (int d = 0; d < NDIFFUSE; d++) {
        if (!(a->diffuse[d] = malloc(a->dlen * sizeof(float))))
            return -1;
        for (size_t i = 0; i < a->dlen; i++)
            a->diffuse[d][i] = (float)sim_rng_gauss(r);
        normalize(a->diffuse[d], a->dlen, a->noise_rms / sqrt(NDIFFUSE));
        double z = 1 - (2.0 * d + 1) / NDIFFUSE, rho = sqrt(1 - z * z), az = d * M_PI * (3 - sqrt(5));
        double u[3] = { rho * cos(az), rho * sin(az), z };
        for (int m = 0; m < mics->n; m++) {
            double proj = 0;
            for (int k = 0; k < 3; k++)
                proj += u[k] * (mics->pos[m][k] - mics->center[k]);
            a->idelay[d][m] = lround(margin - proj / SIM_AUDIO_SPEED_OF_SOUND * a->cfg.rate);
        }
    }
    return 0;
}

/* The noise is set against the loudest source's direct sound at the array's centre, with the
 * robot at its start pose and each source where it starts. */
static double noise_for_snr(const sim_audio_t *a, double snr_db)
{
    double best = 0, c[3];
    const double *pose = a->cfg.start_pose, *mc = a->cfg.mics.center;
    c[0] = pose[0] + cos(pose[2]) * mc[0] - sin(pose[2]) * mc[1];
    c[1] = pose[1] + sin(pose[2]) * mc[0] + cos(pose[2]) * mc[1];
    c[2] = mc[2];
    for (int i = 0; i < a->nsrc; i++) {
        double p[3] = { a->src[i].s.x, a->src[i].s.y, a->src[i].s.z };
        best = fmax(best, a->src[i].s.level / dist3(p, c));
    }
    if (best == 0)
        best = 0.01;
    return snr_db >= 200 ? 0 : best / pow(10, snr_db / 20);
}

sim_audio_t *sim_audio_create(const sim_audio_cfg_t *cfg, const sim_audio_scene_t *scene,
                              const occmap_t *map, char *why, size_t whylen)
{
    if (cfg->rate < 4000 || cfg->rate > 96000 || cfg->block < 16 || cfg->block > 8192 || cfg->mics.n < 1) {
        marie_fail_why(why, whylen, "rate, block or microphones out of range");
        return NULL;
    }
    sim_audio_t *a = calloc(1, sizeof(*a));
    if (!a)
        return NULL;
    a->cfg = *cfg;
    a->nsrc = scene->n;
    a->reflect = scene->reflect;
    a->mask = ~0u;
    a->diffuse_on = true;
    make_table(a);
    sim_rng_t r;
    sim_rng_seed(&r, cfg->seed ^ 0xa0d10);
    for (int i = 0; i < a->nsrc; i++) {
        a->src[i].s = scene->src[i];
        if (load_source(a, &a->src[i], &r, why, whylen))
            goto fail;
    }
    a->noise_rms = noise_for_snr(a, scene->snr_db);
    if (make_diffuse(a, &r))
        goto fail;
    if (map && !(a->map = occmap_clone(map)))
        goto fail;
    return a;
fail:
    sim_audio_destroy(a);
    return NULL;
}

void sim_audio_destroy(sim_audio_t *a)
{
    if (!a)
        return;
    int e = errno;
    for (int i = 0; i < a->nsrc; i++)
        free(a->src[i].sig);
    for (int d = 0; d < NDIFFUSE; d++)
        free(a->diffuse[d]);
    occmap_destroy(a->map);
    free(a);
    errno = e;
}
