/* marie-sim: steps the ODE world on its own pacing and publishes the drivers' channels, the
 * clock and ground truth; obeys the motor command channel (channel mode). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/clear.h"
#include "core/component.h"
#include "sim/camera.h"
#include "sim/audio_port.h"
#include "sim/devices.h"
#include "sim/sim_opts.h"
#include "map/occmap.h"
#include "sim/world.h"

typedef struct {
    sim_world_t *world;
    sim_devices_t *devices;     /* device mode; NULL in channel mode */
    sim_camera_t *camera;       /* NULL when the camera is off */
    marie_port_t *p_camera;
    sim_audio_port_t *audio;    /* the microphone array; NULL without an audio scene */
    marie_port_t *p_enc, *p_gyro, *p_laser, *p_estop, *p_truth, *p_clock;
    const sim_opts_t *o;        /* the parameters (speed, lockstep, cmd_timeout, start_utime, ...) */
    /* publication periods, in physics steps */
    int64_t n_clock, n_enc, n_gyro, n_laser, n_truth, n_estop;
    float *scan;
    int beams;
    marie_timer_t *timer;
    /* pacing: sim time follows anchor_sim + (mono - anchor_mono) * speed */
    int64_t anchor_mono, anchor_sim;
    /* motor commands and lockstep */
    bool have_cmd, cmd_live;
    int64_t last_cmd_sim;       /* sim us when the last command arrived */
    int64_t wait_since;         /* mono us when the lockstep wait began, 0 if not waiting */
    bool have_pose;
    int64_t last_pose_sim;      /* sim us of the newest pose estimate */
    bool pressed, estop_dirty;  /* the e-stop now: the estop parameter at start, then SIM_ESTOP */
    int64_t last_touch;         /* sim us of the last step with a wall contact; -1: never */
    int64_t clock_sent;         /* sim us the clock last said; -1: nothing yet */
} sim_t;

static const marie_port_spec_t ports[] = {
    { "encoders", &marie_type_wheel_encoders_t, MARIE_OUT, MARIE_PUSH, "WHEEL_ENCODERS" },
    { "gyro", &marie_type_gyro_t, MARIE_OUT, MARIE_PUSH, "GYRO" },
    { "laser", &marie_type_laser_scan_t, MARIE_OUT, MARIE_PUSH, "LASER" },
    { "estop", &marie_type_estop_t, MARIE_OUT, MARIE_PUSH, "ESTOP" },
    { "truth", &marie_type_pose_cov_t, MARIE_OUT, MARIE_PUSH, "SIM_TRUTH" },
    { "clock", &marie_type_sim_clock_t, MARIE_OUT, MARIE_PUSH, MARIE_CH_CLOCK },
    { "camera", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "CAMERA_IMAGE" },
    { "motor_command", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "MOTOR_COMMAND" },
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "POSE" },
    { "estop_set", &marie_type_estop_t, MARIE_IN, MARIE_PUSH, "SIM_ESTOP" },
    { "audio", &marie_type_audio_frame_t, MARIE_OUT, MARIE_PUSH, "AUDIO" },
    { "teleport", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "SIM_TELEPORT" },
    { NULL },
};

static const marie_param_spec_t params[] = SIM_OPTS;

static int64_t period_steps(marie_component_t *c, const char *param, double step)
{
    double hz = marie_param_double(c, param);
    if (!(hz > 0) || !isfinite(hz)) {
        marie_component_fail_reason(c, "%s: expected a positive rate", param);
        return -1;
    }
    int64_t n = llround(1.0 / (hz * step));
    return n < 1 ? 1 : n;
}

static int64_t sim_now(const sim_t *s)
{
    return s->o->start_utime + sim_world_time_us(s->world);
}

static void on_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

/* What lockstep waited for has come: step at once rather than at the next poll. */
static void resume(marie_component_t *c, sim_t *s)
{
    s->wait_since = 0;
    s->anchor_mono = marie_mono_us();
    s->anchor_sim = sim_now(s);
    marie_loop_add_wall_oneshot(marie_component_loop(c), 0, on_timer, c);
}

static void on_motor_command(marie_component_t *c, marie_port_t *p, const void *msg,
                             const marie_msg_info_t *info)
{
    sim_t *s = marie_component_user(c);
    const marie_motor_command_t *m = msg;
    if (!isfinite(m->v) || !isfinite(m->omega)) {
        marie_component_bad_input(c, "bad_motor_command", "motor command with a non-finite v or omega");
        return;
    }
    if (!s->world)
        return;
    /* In device mode marie-drives obeys the command over CAN; here it only paces lockstep. */
    if (!s->devices)
        sim_world_set_velocity(s->world, m->v, m->omega);
    s->have_cmd = s->cmd_live = true;
    /* A controller on the sim clock stamps its command with the sim time it decided at;
     * lockstep counts from there (the receipt time would include the bus latency, during
     * which an unpaced simulator runs on). Other stamps fall back to the receipt time. */
    int64_t now = sim_now(s);
    s->last_cmd_sim = m->utime <= now && m->utime >= now - 10000000 ? m->utime : now;
    marie_debug("motor command v %.3f omega %.3f stamped %.3f s at %.3f s", m->v, m->omega, m->utime / 1e6,
                now / 1e6);
    if (s->wait_since)
        resume(c, s);       /* the command we waited for: pacing from here, no catch-up burst */
}

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    sim_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    int64_t now = s->world ? sim_now(s) : 0;
    if (s->o->lockstep_pose <= 0 || m->utime > now || m->utime < s->last_pose_sim)
        return;
    s->last_pose_sim = m->utime;
    s->have_pose = true;
    if (s->wait_since)
        resume(c, s);
}

static void on_estop_set(marie_component_t *c, marie_port_t *p, const void *msg,
                         const marie_msg_info_t *info)
{
    sim_t *s = marie_component_user(c);
    const marie_estop_t *m = msg;
    if (s->pressed != (bool)m->pressed) {
        s->pressed = m->pressed;
        s->estop_dirty = true;
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "estop", "e-stop %s by %s",
                              m->pressed ? "pressed" : "released", m->source ? m->source : "?");
    }
}

/* The kidnapped robot: carried to another pose with no wheel turning (tests, evaluation). */
static void on_teleport(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    sim_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    if (!s->world || sim_world_teleport(s->world, m->pose.x, m->pose.y, m->pose.theta) < 0) {
        marie_component_bad_input(c, "bad_teleport", "cannot carry the robot to (%g, %g, %g): not a free spot",
                                  m->pose.x, m->pose.y, m->pose.theta);
        return;
    }
    marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "teleport", "robot carried to (%.2f, %.2f, %.2f)", m->pose.x,
                          m->pose.y, m->pose.theta);
}

/* The drivers' channels (channel mode only): encoders, gyro, laser. */
static void publish_sensors(sim_t *s, int64_t k, int64_t now)
{
    if (k % s->n_enc == 0) {
        int32_t l, r;
        double la, ra, ls, rs;
        sim_world_encoders(s->world, &l, &r);
        sim_world_wheels(s->world, &la, &ra, &ls, &rs);
        marie_wheel_encoders_t e = {
            .utime = now, .left_ticks = l, .right_ticks = r,
            .ticks_per_rev = sim_world_params(s->world)->ticks_per_rev,
            .left_velocity = ls, .right_velocity = rs,
            .status = s->pressed ? MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP : MARIE_WHEEL_ENCODERS_T_STATUS_OK,
        };
        marie_port_publish(s->p_enc, &e);
    }
    if (k % s->n_gyro == 0) {
        /* As marie-gyro publishes after its standstill calibration: what is left of the bias
         * (gyro_bias) stays in the rate. */
        marie_gyro_t g = { .utime = now, .yaw_rate = sim_world_gyro(s->world), .bias = 0.0,
                           .bias_valid = 1, .status = 0 };
        marie_port_publish(s->p_gyro, &g);
    }
    if (k % s->n_laser == 0) {
        const sim_params_t *p = sim_world_params(s->world);
        sim_world_laser(s->world, s->scan, s->beams);
        marie_laser_scan_t l = {
            .utime = now, .angle_min = (float)(-p->laser_fov / 2),
            .angle_increment = (float)(p->laser_fov / (s->beams - 1)),
            .range_min = (float)p->laser_min, .range_max = (float)p->laser_max,
            .nranges = s->beams, .ranges = s->scan, .nintensities = 0, .intensities = NULL,
        };
        marie_port_publish(s->p_laser, &l);
    }
}

static void publish_clock(sim_t *s, int64_t now)
{
    if (now == s->clock_sent)
        return;
    marie_sim_clock_t ck = { .utime = now, .speed = s->o->speed };
    marie_port_publish(s->p_clock, &ck);
    s->clock_sent = now;
}

static void publish(marie_component_t *c, sim_t *s)
{
    int64_t k = sim_world_steps(s->world), now = sim_now(s);
    if (!s->devices)
        publish_sensors(s, k, now);
    if (s->camera) {
        double x, y, th;
        sim_world_pose(s->world, &x, &y, &th);
        sim_camera_publish(s->camera, c, s->p_camera, k, x, y, th, now);
    }
    if (s->audio) {
        double pose[3];
        sim_world_pose(s->world, &pose[0], &pose[1], &pose[2]);
        sim_audio_port_step(s->audio, now, pose);
    }
    if (k % s->n_truth == 0) {
        marie_pose_cov_t t = { .utime = now, .frame = "map" };
        sim_world_pose(s->world, &t.pose.x, &t.pose.y, &t.pose.theta);
        marie_port_publish(s->p_truth, &t);
    }
    /* Both modes: no GPIO can be emulated here, so the simulator plays marie-gpio. */
    if (k % s->n_estop == 0 || s->estop_dirty) {
        marie_estop_t e = { .utime = now, .pressed = s->pressed, .source = "sim" };
        marie_port_publish(s->p_estop, &e);
        s->estop_dirty = false;
    }
    /* The clock goes last, so a component woken by it already has this instant's data. */
    if (k % s->n_clock == 0)
        publish_clock(s, now);
}

/* Lockstep on one input last seen at *last (sim us): true while the simulator waits for it. */
static bool lockstep_holds(marie_component_t *c, sim_t *s, int64_t *last, double horizon, int64_t now)
{
    if (now - *last <= (int64_t)(horizon * 1e6))
        return false;
    int64_t mono = marie_mono_us();
    if (!s->wait_since) {
        s->wait_since = mono;
        marie_component_count(c, "lockstep_waits", 1);
        marie_debug("lockstep: waiting at %.3f s for an input of %.3f s", now / 1e6, *last / 1e6);
    }
    if (mono - s->wait_since < (int64_t)(s->o->lockstep_timeout * 1e6))
        return true;
    /* The controller is gone or slow: go on, and wait again one lockstep later. */
    marie_component_count(c, "lockstep_timeouts", 1);
    s->wait_since = 0;
    *last = now;
    s->anchor_mono = mono;
    s->anchor_sim = now;
    return false;
}

/* One physics step with its inputs and outputs; false when lockstep says wait. */
static bool step_once(marie_component_t *c, sim_t *s)
{
    int64_t now = sim_now(s);
    if ((s->o->lockstep > 0 && s->have_cmd && lockstep_holds(c, s, &s->last_cmd_sim, s->o->lockstep, now)) ||
        (s->have_pose && lockstep_holds(c, s, &s->last_pose_sim, s->o->lockstep_pose, now)))
        return false;
    if (!s->devices && s->cmd_live && now - s->last_cmd_sim > (int64_t)(s->o->cmd_timeout * 1e6)) {
        /* The drives' own watchdog: no command, no motion. */
        sim_world_set_velocity(s->world, 0, 0);
        s->cmd_live = false;
        marie_component_count(c, "cmd_timeouts", 1);
    }
    if (s->devices && !sim_devices_may_step(s->devices))
        return false;       /* the drivers lag behind: their devices must not judge them dead */
    sim_world_set_estop(s->world, s->pressed);
    if (s->devices)
        sim_devices_before_step(s->devices);
    sim_world_step(s->world);
    if (s->devices) {
        if (sim_devices_laser_sends(s->devices, sim_now(s)))
            publish_clock(s, sim_now(s));
        sim_devices_after_step(s->devices, sim_world_step_s(s->world), sim_now(s));
    }
    /* Heartbeat counters: "collisions" counts each new contact with a wall (contacts that
     * flicker while the robot scrapes along one count once). */
    bool touching = sim_world_wall_contacts(s->world) > 0;
    if (touching && (s->last_touch < 0 || sim_now(s) - s->last_touch > 200000)) {
        marie_component_count(c, "collisions", 1);
        double x, y, th;
        sim_world_pose(s->world, &x, &y, &th);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "collision", "robot hit a wall at (%.2f, %.2f) at %.3f s",
                              x, y, sim_now(s) / 1e6);
    }
    if (touching)
        s->last_touch = sim_now(s);
    publish(c, s);
    return true;
}

static void on_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    marie_component_t *c = user;
    sim_t *s = marie_component_user(c);
    if (marie_component_state(c) != MARIE_STATE_RUNNING || !s->world)
        return;
    int64_t steps0 = sim_world_steps(s->world);
    if (s->o->speed <= 0) {
        /* As fast as possible, but back to the loop every clock period so commands and
         * lifecycle orders are read between bursts. While waiting, look again every 1 ms
         * instead of spinning (an awaited input steps at once through resume()). */
        bool held = false;
        for (int64_t i = 0; i < s->n_clock && !held; i++)
            held = !step_once(c, s);
        if (s->timer)
            marie_timer_set_period(s->timer, held ? 1000 : 1);
    } else {
        int64_t mono = marie_mono_us();
        int64_t target = s->anchor_sim + (int64_t)((mono - s->anchor_mono) * s->o->speed);
        if (target - sim_now(s) > 250000) {
            /* Too far behind (a slow machine or a stall): drop the debt rather than burst. */
            marie_component_count(c, "behind", 1);
            s->anchor_mono = mono;
            s->anchor_sim = sim_now(s);
            target = s->anchor_sim + (int64_t)(1000 * s->o->speed);
        }
        while (sim_now(s) < target)
            if (!step_once(c, s))
                break;
    }
    int64_t stepped = sim_world_steps(s->world) - steps0;
    if (stepped) {
        marie_component_count(c, "steps", stepped);
        /* Simulated time in the heartbeat, so `marie ps` shows how fast the world runs. */
        int64_t ms = sim_world_time_us(s->world) / 1000;
        marie_component_count(c, "sim_ms", ms - marie_component_counter(c, "sim_ms"));
    }
    if (s->devices) {
        const sim_devices_stats_t *ds = sim_devices_stats(s->devices);
        marie_component_count(c, "driver_waits", ds->driver_waits - marie_component_counter(c, "driver_waits"));
        marie_component_count(c, "driver_timeouts",
                              ds->driver_timeouts - marie_component_counter(c, "driver_timeouts"));
        marie_component_count(c, "can_dropped", (int64_t)ds->can_dropped - marie_component_counter(c, "can_dropped"));
    }
}

/* The start pose is checked against the map, never left to the physics: a robot placed in a
 * wall is thrown out of it, one placed off the map drives in nothing. */
static int place_robot(marie_component_t *c, const occmap_t *map, sim_params_t *p)
{
    const char *how = sim_opts(c)->start;
    double lx, ly;
    sim_world_footprint(p, &lx, &ly);
    marie_info("robot: chassis %.2f x %.2f m (robot_radius %.2f)", lx, ly, p->robot_radius);
    if (strcmp(how, "auto") == 0) {
        double x, y;
        if (occmap_nearest_clear(map, p->start_x, p->start_y, hypot(lx, ly) / 2 + 0.05, &x, &y) < 0) {
            marie_component_fail_reason(c, "start: auto: no free spot in the map has room for the robot");
            return -1;
        }
        if (x != p->start_x || y != p->start_y)
            marie_info("start: auto: (%.2f, %.2f) moved to (%.2f, %.2f)", p->start_x, p->start_y, x, y);
        p->start_x = x;
        p->start_y = y;
        return 0;
    }
    if (strcmp(how, "given") != 0) {
        marie_component_fail_reason(c, "start: expected given or auto, got '%s'", how);
        return -1;
    }
    if (occmap_footprint_clear(map, p->start_x, p->start_y, p->start_theta, lx, ly))
        return 0;
    int cx, cy;
    const char *where = !occmap_cell(map, p->start_x, p->start_y, &cx, &cy) ? "outside the map"
                        : occmap_get(map, cx, cy) == OCCMAP_OCCUPIED      ? "in an occupied cell"
                        : occmap_get(map, cx, cy) != OCCMAP_FREE          ? "in an unknown cell"
                                                                          : "with a wall under the robot";
    marie_component_fail_reason(c, "start (%.2f, %.2f) is %s (map %.1f x %.1f m from (%.2f, %.2f)); give a free "
                                "start or start: auto", p->start_x, p->start_y, where, map->width * map->resolution,
                                map->height * map->resolution, map->origin_x, map->origin_y);
    return -1;
}

/* Everything init builds, let go (devices first: they step the world). */
static void release(sim_t *s)
{
    MARIE_CLEAR(s->devices, sim_devices_destroy);
    MARIE_CLEAR(s->camera, sim_camera_destroy);
    MARIE_CLEAR(s->audio, sim_audio_port_destroy);
    MARIE_CLEAR(s->world, sim_world_destroy);
    MARIE_CLEAR(s->scan, free);
}

static int on_init(marie_component_t *c)
{
    sim_t *s = marie_component_user(c);
    /* Init again after a failure: start from nothing. */
    release(s);
    s->last_touch = -1;
    s->clock_sent = -1;
    const sim_opts_t *o = s->o = sim_opts(c);
    bool device = strcmp(o->mode, "device") == 0;
    if (!device && strcmp(o->mode, "channel") != 0) {
        marie_component_fail_reason(c, "mode: expected channel or device, got '%s'", o->mode);
        return -1;
    }
    char path[4096];
    occmap_world_path(o->world, path, sizeof(path));
    marie_errors_t errs = { 0 };
    occmap_t *map = occmap_load(path, &errs);
    if (!map) {
        marie_errors_print(&errs, stderr);
        marie_component_fail_reason(c, "world %s: %s", path, errs.n ? errs.msgs[0] : "cannot load");
        marie_errors_clear(&errs);
        return -1;
    }
    sim_params_t p = o->model;
    if (place_robot(c, map, &p) < 0)
        goto fail;
    if (device) {
        /* The virtual LMS200 resamples 361 beams to the resolution its driver asks for, and
         * the virtual drives ramp the velocity themselves. */
        p.laser_beams = 361;
        p.accel = 100.0;
    }
    if (p.laser_beams != 181 && p.laser_beams != 361) {
        marie_component_fail_reason(c, "laser_beams: expected 181 or 361, got %ld", (long)p.laser_beams);
        goto fail;
    }
    if (!(p.step > 0 && p.step <= 0.02)) {
        marie_component_fail_reason(c, "step: expected 0 < step <= 0.02 s");
        goto fail;
    }
    s->pressed = o->estop;
    if (!(s->o->speed >= 0) || !isfinite(s->o->speed)) {
        marie_component_fail_reason(c, "speed: expected 0 (as fast as possible) or a positive factor");
        goto fail;
    }
    if ((s->n_clock = period_steps(c, "clock_hz", p.step)) < 0 ||
        (s->n_enc = period_steps(c, "encoders_hz", p.step)) < 0 ||
        (s->n_gyro = period_steps(c, "gyro_hz", p.step)) < 0 ||
        (s->n_estop = period_steps(c, "estop_hz", p.step)) < 0 ||
        (s->n_laser = period_steps(c, "laser_hz", p.step)) < 0 ||
        (s->n_truth = period_steps(c, "truth_hz", p.step)) < 0)
        goto fail;
    s->beams = p.laser_beams;
    s->scan = calloc((size_t)s->beams, sizeof(float));
    s->world = s->scan ? sim_world_create(map, &p) : NULL;
    if (!s->world) {
        marie_component_fail_reason(c, "cannot build the world: %s", strerror(errno));
        goto fail;
    }
    if (sim_camera_init(c, path, map, p.step, &s->camera) < 0)
        goto fail;
    if (sim_audio_port_create(c, map, (double[3]){ p.start_x, p.start_y, p.start_theta }, p.seed,
                              s->o->start_utime, &s->audio))
        goto fail;
    MARIE_CLEAR(map, occmap_destroy);
    if (device) {
        const sim_devices_cfg_t *dc = &o->devices;
        char why[512];
        s->devices = sim_devices_create(dc, s->world, marie_component_loop(c), sim_now(s), why, sizeof(why));
        if (!s->devices) {
            marie_component_fail_reason(c, "device mode: %s", why);
            goto fail;
        }
        marie_info("device mode: drives %d/%d and gyro %d on %s, LMS200 on %s (%s)", (int)dc->left_node,
                   (int)dc->right_node, (int)dc->gyro_node, dc->can, dc->laser_link,
                   sim_devices_laser_path(s->devices));
    }
    s->p_enc = marie_port(c, "encoders");
    s->p_gyro = marie_port(c, "gyro");
    s->p_laser = marie_port(c, "laser");
    s->p_estop = marie_port(c, "estop");
    s->p_truth = marie_port(c, "truth");
    s->p_clock = marie_port(c, "clock");
    s->p_camera = marie_port(c, "camera");
    marie_port_on_message(marie_port(c, "motor_command"), on_motor_command);
    marie_port_on_message(marie_port(c, "pose"), on_pose);
    marie_port_on_message(marie_port(c, "estop_set"), on_estop_set);
    marie_port_on_message(marie_port(c, "teleport"), on_teleport);
    marie_info("world %s: %ld wall boxes, start (%.2f, %.2f, %.2f), speed %g%s", path,
               sim_world_wall_boxes(s->world), p.start_x, p.start_y, p.start_theta, s->o->speed,
               s->o->lockstep > 0 ? ", lockstep" : "");
    return 0;
fail:
    release(s);
    occmap_destroy(map);
    return -1;
}

static int arm(marie_component_t *c)
{
    sim_t *s = marie_component_user(c);
    s->anchor_mono = marie_mono_us();
    s->anchor_sim = sim_now(s);
    s->wait_since = 0;
    if (s->o->lockstep > 0 && !s->have_cmd) {
        /* Lockstep holds from the start: the controller gets its first clock ticks and then
         * the simulator waits for it, instead of racing ahead while it starts up. */
        s->have_cmd = true;
        s->last_cmd_sim = sim_now(s);
    }
    /* Speed 0 polls with a zero timeout between bursts; otherwise 1 ms wall pacing. */
    s->timer = marie_loop_add_wall_timer(marie_component_loop(c), s->o->speed > 0 ? 1000 : 1, on_timer, c);
    if (!s->timer) {
        marie_component_fail_reason(c, "cannot add the step timer: %s", strerror(errno));
        return -1;
    }
    return 0;
}

static void disarm(marie_component_t *c)
{
    sim_t *s = marie_component_user(c);
    marie_loop_remove_timer(marie_component_loop(c), s->timer);
    s->timer = NULL;
}

static int on_start(marie_component_t *c)
{
    return arm(c);
}

static int on_stop(marie_component_t *c)
{
    sim_t *s = marie_component_user(c);
    disarm(c);
    if (s->world)
        sim_world_set_velocity(s->world, 0, 0);
    return 0;
}

static int on_pause(marie_component_t *c)
{
    disarm(c);          /* simulated time stands still */
    return 0;
}

static void on_abort(marie_component_t *c)
{
    disarm(c);
}

static void on_quit(marie_component_t *c)
{
    sim_t *s = marie_component_user(c);
    disarm(c);
    release(s);
}

static const marie_component_def_t def = {
    .kind = "sim",
    .ports = ports,
    .params = params, .params_size = sizeof(sim_opts_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_stop = on_stop,
    .on_pause = on_pause,
    .on_resume = on_start,       /* the clock goes on where it stood */
    .on_abort = on_abort,
    .on_quit = on_quit,
};

/* Shorthands: --speed N, --world W, --seed S, --lockstep T, --mode M become --param KEY=VALUE. */
int main(int argc, char **argv)
{
    static const char *const shorthands[] = { "speed", "world", "seed", "lockstep", "mode", NULL };
    char **args = calloc(2 * (size_t)argc + 1, sizeof(char *));   /* each shorthand at most doubles */
    char **owned = calloc((size_t)argc + 1, sizeof(char *));
    if (!args || !owned)
        return 1;
    int n = 0, nowned = 0;
    args[n++] = argv[0];
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int matched = 0;
        for (int k = 0; shorthands[k] && !matched; k++) {
            size_t l = strlen(shorthands[k]);
            if (strncmp(a, "--", 2) || strncmp(a + 2, shorthands[k], l))
                continue;
            const char *val = NULL;
            if (a[2 + l] == '=')
                val = a + 3 + l;
            else if (a[2 + l] == 0 && i + 1 < argc)
                val = argv[++i];
            else
                continue;
            char *p;
            if (asprintf(&p, "%s=%s", shorthands[k], val) < 0)
                return 1;
            args[n++] = "--param";
            args[n++] = owned[nowned++] = p;
            matched = 1;
        }
        if (!matched)
            args[n++] = argv[i];
    }
    args[n] = NULL;
    sim_t s = { 0 };
    int rc = marie_main(&def, n, args, &s);
    for (int i = 0; i < nowned; i++)
        free(owned[i]);
    free(owned);
    free(args);
    return rc;
}
