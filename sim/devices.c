/* devices: glue between the ODE world and the hw/ device emulators (vdevices, vlms200). */
#include "sim/devices.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/log.h"
#include "core/time.h"
#include "hw/can/canbus.h"
#include "hw/drives/vdevices.h"
#include "hw/lms200/vlms200.h"

#define SCAN_BEAMS 361

/* A reader that leaves data unread: since when (sim us; -1: it is up to date), and since when
 * (mono us; 0: not) it counts as gone: it kept us waiting too long, so the world runs on for a
 * while without waiting for it, until it has caught up or that while is over. */
typedef struct {
    int64_t since;
    int64_t gone_at;
} lag_t;

static void lag_note(lag_t *l, bool unread, int64_t now, int64_t mono, int64_t hold)
{
    if (l->gone_at && mono - l->gone_at >= hold)
        l->gone_at = 0;         /* look at it again: frozen, or only slow? */
    if (!unread) {
        l->since = -1;
        l->gone_at = 0;
    } else if (l->since < 0) {
        l->since = now;
    }
}

static bool lag_over(const lag_t *l, int64_t now, int64_t max)
{
    return !l->gone_at && l->since >= 0 && now - l->since > max;
}

/* The parameters' seconds in us, the devices' clock. */
static int64_t us(double s)
{
    return (int64_t)(s * 1e6);
}

struct sim_devices {
    sim_world_t *world;
    marie_loop_t *loop;
    can_emubus_t *bus;
    vdevices_t *dev;
    vlms200_t *laser;
    int laser_fd;               /* as registered with the loop */
    short laser_events;
    int64_t now;                /* simulated us: every device's clock */
    /* driver lockstep: the devices never run more than driver_lag (sim s) ahead of their
     * drivers; driver_wait (wall s) before a lagging driver counts as gone; laser_hold: a
     * telegram unread holds the world at once */
    sim_devices_cfg_t cfg;
    uint64_t rx_seen;           /* frames from the CAN master counted at the last look */
    int64_t last_rx;            /* sim us of the newest frame from the master; -1: none, or gone */
    lag_t laser_lag, can_lag;   /* the laser's host, and the CAN clients, leaving data unread */
    int64_t wait_since;         /* mono us when the wait began, 0 if not waiting */
    float scan[SCAN_BEAMS];
    sim_devices_stats_t st;
};

static void on_dev(marie_loop_t *loop, int fd, short revents, void *user)
{
    sim_devices_t *d = user;
    /* The devices run on simulated time, as the drivers on the other end of the bus do under
     * `--clock sim`; the master lockstep keeps the two within master_lag of each other. */
    if (vdevices_process(d->dev, d->now) < 0 && errno == EPIPE)
        marie_warn_ratelimited(5, "device mode: the CAN bus went away");
}

static void laser_sync_fd(sim_devices_t *d);

static void on_laser(marie_loop_t *loop, int fd, short revents, void *user)
{
    sim_devices_t *d = user;
    vlms200_io(d->laser, revents, d->now);
    laser_sync_fd(d);
}

/* The pty's fd changes on a re-plug and the events with pending output: re-register. */
static void laser_sync_fd(sim_devices_t *d)
{
    int fd = vlms200_fd(d->laser);
    short ev = fd >= 0 ? vlms200_events(d->laser) : 0;
    if (fd == d->laser_fd && ev == d->laser_events)
        return;
    if (d->laser_fd >= 0)
        marie_loop_remove_fd(d->loop, d->laser_fd);
    d->laser_fd = -1;
    if (fd >= 0 && marie_loop_add_fd(d->loop, fd, ev, on_laser, d) == 0)
        d->laser_fd = fd;
    d->laser_events = ev;
}

/* The device is about to send a scan: give it this instant's ranges. */
static void on_scan(void *user, vlms200_t *v, int64_t now_us)
{
    sim_devices_t *d = user;
    const sim_params_t *p = sim_world_params(d->world);
    int n = sim_world_laser(d->world, d->scan, SCAN_BEAMS);
    for (int i = 0; i < n; i++)
        if (d->scan[i] >= p->laser_max)
            d->scan[i] = NAN;           /* no echo, not a wall at the range limit */
    vlms200_set_ranges(v, d->scan, (size_t)n);
    d->st.laser_scans++;
}

sim_devices_t *sim_devices_create(const sim_devices_cfg_t *cfg, sim_world_t *world, marie_loop_t *loop,
                                  int64_t now, char *err, size_t errlen)
{
    sim_devices_t *d = calloc(1, sizeof(*d));
    if (!d) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    d->world = world;
    d->loop = loop;
    d->laser_fd = -1;
    d->now = now;
    d->cfg = *cfg;
    d->last_rx = d->laser_lag.since = d->can_lag.since = -1;
    if (sim_world_params(world)->laser_beams != SCAN_BEAMS) {
        marie_fail_why(err, errlen, "device mode needs the world's laser at %d beams", SCAN_BEAMS);
        goto fail;
    }
    if (cfg->can_serve) {
        if (strncmp(cfg->can, "emu:", 4) != 0) {
            marie_fail_why(err, errlen, "can_serve needs an emu:PATH bus, not '%s'", cfg->can);
            goto fail;
        }
        d->bus = can_emubus_create(loop, cfg->can + 4);
        if (!d->bus) {
            snprintf(err, errlen, "cannot serve the emulated CAN bus at %s: %s", cfg->can + 4,
                     strerror(errno));
            goto fail;
        }
    }
    const sim_params_t *p = sim_world_params(world);
    vdevices_cfg_t vc;
    vdevices_cfg_default(&vc);
    vc.can = cfg->can;
    vc.left = cfg->left_node;
    vc.right = cfg->right_node;
    vc.gyro = cfg->gyro_node;
    vc.drive.ticks_per_rev = p->ticks_per_rev;
    vc.wheel_radius = p->wheel_radius;
    vc.track_width = p->track;
    vc.vgyro.bias = cfg->vgyro_bias;
    vc.vgyro.noise = p->gyro_noise;
    vc.external_physics = true;         /* ODE turns the wheels */
    d->dev = vdevices_create(&vc, now);
    if (!d->dev) {
        snprintf(err, errlen, "cannot attach the virtual drives and gyro to %s: %s", cfg->can,
                 strerror(errno));
        goto fail;
    }
    if (marie_loop_add_fd(loop, vdevices_fd(d->dev), POLLIN, on_dev, d) < 0) {
        snprintf(err, errlen, "cannot poll the devices' bus connection: %s", strerror(errno));
        goto fail;
    }
    vlms200_cfg_t lc = VLMS200_DEFAULTS;
    lc.rate_hz = cfg->laser_hz;
    lc.line_time = true;
    d->laser = vlms200_create(&lc);
    if (!d->laser || vlms200_open(d->laser, cfg->laser_link) < 0) {
        snprintf(err, errlen, "cannot create the virtual LMS200 pty%s%s: %s", cfg->laser_link ? " at " : "",
                 cfg->laser_link ? cfg->laser_link : "", strerror(errno));
        goto fail;
    }
    vlms200_on_scan(d->laser, on_scan, d);
    laser_sync_fd(d);
    return d;
fail:
    MARIE_KEEP_ERRNO(sim_devices_destroy(d));
    return NULL;
}

void sim_devices_destroy(sim_devices_t *d)
{
    if (!d)
        return;
    if (d->laser_fd >= 0)
        marie_loop_remove_fd(d->loop, d->laser_fd);
    vlms200_destroy(d->laser);
    if (d->dev) {
        marie_loop_remove_fd(d->loop, vdevices_fd(d->dev));
        vdevices_destroy(d->dev);
    }
    can_emubus_destroy(d->bus);
    free(d);
}

void sim_devices_before_step(sim_devices_t *d)
{
    vdrive_t *l = vdevices_drive(d->dev, 0), *r = vdevices_drive(d->dev, 1);
    sim_world_set_wheels(d->world, l ? vdrive_command(l) : 0.0, r ? vdrive_command(r) : 0.0);
}

bool sim_devices_laser_sends(const sim_devices_t *d, int64_t now)
{
    return d->laser && vlms200_sends_at(d->laser, now);
}

void sim_devices_after_step(sim_devices_t *d, double dt, int64_t now)
{
    d->now = now;
    double la, ra, ls, rs, v, om;
    sim_world_wheels(d->world, &la, &ra, &ls, &rs);
    vdrive_t *l = vdevices_drive(d->dev, 0), *r = vdevices_drive(d->dev, 1);
    if (l)
        vdrive_set_feedback(l, la, ls);
    if (r)
        vdrive_set_feedback(r, ra, rs);
    sim_world_velocity(d->world, &v, &om);
    if (vdevices_gyro(d->dev))
        vgyro_set_rate(vdevices_gyro(d->dev), om);
    /* Relay what the drivers sent while we stepped, so the devices judge their deadlines
     * on every frame already sent (we are the bus too when serving it). */
    if (d->bus)
        can_emubus_process(d->bus);
    vdevices_tick(d->dev, dt, now);
    vlms200_tick(d->laser, now);
    laser_sync_fd(d);
}

/* The master's periodic frames (SYNC, heartbeat): not any frame, or another master's SDO
 * traffic would keep the drives' master for alive. */
static void note_drivers(sim_devices_t *d)
{
    uint64_t in = vdevices_stats(d->dev)->master_frames_in;
    if (in != d->rx_seen) {
        d->rx_seen = in;
        d->last_rx = d->now;
    }
    int64_t mono = marie_mono_us();
    lag_note(&d->laser_lag, vlms200_unread(d->laser) > 0, d->now, mono, us(d->cfg.driver_wait));
    if (d->bus)
        lag_note(&d->can_lag, can_emubus_unread(d->bus) > 0, d->now, mono, us(d->cfg.driver_wait));
}

bool sim_devices_may_step(sim_devices_t *d)
{
    note_drivers(d);
    bool master = d->last_rx >= 0 && d->now - d->last_rx > us(d->cfg.driver_lag);
    bool laser = d->cfg.laser_hold ? !d->laser_lag.gone_at && vlms200_host_unread(d->laser) > 0
                                   : lag_over(&d->laser_lag, d->now, us(d->cfg.driver_lag));
    bool can = lag_over(&d->can_lag, d->now, us(d->cfg.driver_lag));
    if (us(d->cfg.driver_lag) <= 0 || (!master && !laser && !can)) {
        d->wait_since = 0;
        return true;
    }
    int64_t mono = marie_mono_us();
    if (!d->wait_since) {
        d->wait_since = mono;
        d->st.driver_waits++;
    }
    if (mono - d->wait_since < us(d->cfg.driver_wait))
        return false;
    /* The driver is gone or frozen: run on, and let the deadlines on both sides (on simulated
     * time) find it dead, as they would on a real bus. Its next frame or read re-arms the wait. */
    d->st.driver_timeouts++;
    d->wait_since = 0;
    if (master)
        d->last_rx = -1;
    if (laser) {
        d->laser_lag.gone_at = mono;
        d->laser_lag.since = d->now;
    }
    if (can) {
        d->can_lag.gone_at = mono;
        d->can_lag.since = d->now;
    }
    return true;
}

const sim_devices_stats_t *sim_devices_stats(sim_devices_t *d)
{
    /* The bus's counts are read when asked, not copied at every step. */
    const vdevices_stats_t *v = vdevices_stats(d->dev);
    d->st.can_frames_in = v->frames_in;
    d->st.can_frames_out = v->frames_out;
    d->st.can_dropped = v->frames_dropped + (d->bus ? can_emubus_stats(d->bus)->overflow : 0);
    return &d->st;
}

const char *sim_devices_laser_path(const sim_devices_t *d)
{
    return vlms200_path(d->laser);
}
