/* marie-localizer: Monte Carlo localization of the robot on a map from odometry and laser. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "map/occmap.h"
#include "adapters/common/posebuf.h"
#include "adapters/common/scanwait.h"
#include "adapters/localizer/mcl.h"
#include "adapters/localizer/seek.h"
#include "core/clear.h"
#include "core/component.h"
#include "adapters/localizer/localizer_params.h"

typedef struct {
    const loc_params_t *q;
    mcl_t *f;
    posebuf_t odom;             /* recent odometry, for the odometry pose at a scan's time */
    scanwait_t wait;            /* a scan newer than the newest odometry */
    int64_t last_cloud;
    double cloud_period_us;
    float *cloud_buf;
    double last_distance;       /* odometry's distance travelled: it only grows, unless restarted */
    double last_v, last_omega;  /* odometry's last body velocity */
    int force_left;             /* sensor updates still forced after a (re)initialisation */
    int64_t first_pub_utime;    /* utime of this run's first pose; 0 before */
    /* Lost: scans that contradict the map at the estimate this many times running mean the robot
     * is not where the filter thinks; it then searches the whole map (seek.h), turning on the spot
     * and driving on, and says so in its heartbeat. */
    int poor;
    seek_t seek;
    bool seek_at_start;         /* search from the next scan (init_mode global; a search whose odometry restarted) */
    int64_t lost_since;         /* scan time the loss was declared */
    int64_t last_judged;        /* scan time of the last filter update or standing check */
    reloc_cloud_t *doubts;      /* the scans of a doubtful while, searched for over the map */
    int64_t last_doubt;         /* scan time of the last such search */
} loc_t;

/* Particles per cloud message: cloud_max, at least one (cloud_buf holds that many). */
static int cloud_max(const loc_params_t *q)
{
    return q->cloud_max < 1 ? 1 : (int)q->cloud_max;
}

static void publish_cloud(marie_component_t *c, loc_t *s, int64_t utime)
{
    int n = mcl_particles(s->f, s->cloud_buf, cloud_max(s->q));
    float *x = malloc(sizeof(float) * 4 * (size_t)(n ? n : 1));
    if (!x)
        return;
    float *y = x + n, *th = y + n, *w = th + n;
    for (int i = 0; i < n; i++) {
        x[i] = s->cloud_buf[4 * i];
        y[i] = s->cloud_buf[4 * i + 1];
        th[i] = s->cloud_buf[4 * i + 2];
        w[i] = s->cloud_buf[4 * i + 3];
    }
    marie_particle_cloud_t m = { .utime = utime, .frame = "map", .n = n, .x = x, .y = y, .theta = th, .weight = w };
    marie_port_publish(marie_port(c, "particles"), &m);
    free(x);
}

static void publish_search(marie_component_t *c, int64_t utime, double v, double omega)
{
    marie_motor_command_t m = { .utime = utime, .v = v, .omega = omega, .source = "relocalize" };
    marie_port_publish(marie_port(c, "search"), &m);
}

static void declare_lost(marie_component_t *c, loc_t *s, const double odom[3], const mcl_fit_t *fit, int64_t utime)
{
    s->poor = 0;
    s->lost_since = utime;
    seek_begin(&s->seek, odom, (double)utime / 1e6);
    marie_component_count(c, "kidnaps_detected", 1);
    marie_component_set_degraded(c, true, "lost: %s", seek_doing(&s->seek));
    marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "lost", "%d of %d beams contradict the map at the estimate "
                          "(%d on walls, %d short of them) for %d checks: the robot is not where it was thought; "
                          "searching the whole map", fit->through, fit->hit + fit->through, fit->hit, fit->shorter,
                          (int)s->q->lost_checks);
}

/* Whether the scans of a doubtful while fit clearly better somewhere else than at the estimate
 * (odometry pose odom now): another place, 1 m or 20 degrees from it, puts most of their points
 * on walls and sees through none, and beats the estimate's own place by the search's margin. */
static bool fits_elsewhere(marie_component_t *c, loc_t *s, const double odom[3])
{
    reloc_hyp_t h[4], here;
    int n = reloc_search(s->f, s->doubts, h, 4);
    marie_component_count(c, "doubt_searches", 1);
    double est[3], cov[9], origin[3], now[3];
    mcl_pose_at(s->f, odom, est, cov);
    reloc_cloud_origin(s->doubts, est, odom, origin);
    reloc_judge_at(s->f, s->doubts, origin, &here);
    int best = -1;
    for (int i = 0; i < n && best < 0; i++)
        if (hypot(h[i].x - here.x, h[i].y - here.y) >= 1.0 || fabs(remainder(h[i].theta - here.theta, 2 * M_PI)) >= 0.35)
            best = i;
    if (best < 0)
        return false;
    reloc_cloud_pose_now(s->doubts, (const double[3]){ h[best].x, h[best].y, h[best].theta }, odom, now);
    bool elsewhere = h[best].score - here.score >= s->q->seek.margin && h[best].hit >= s->q->seek.min_hit &&
                     h[best].contradiction <= s->q->seek.max_contradiction / 2;
    marie_info("doubt: the scans fit at (%.2f, %.2f) with %.3f per point, %.0f%% on walls, %.0f%% through them; "
               "at the estimate (%.2f, %.2f) with %.3f: %s", now[0], now[1], h[best].score, 100 * h[best].hit,
               100 * h[best].contradiction, est[0], est[1], here.score, elsewhere ? "lost" : "the estimate holds");
    return elsewhere;
}

/* A scan judged at the estimate (after an update, or standing still). Contradicted lost_checks
 * times running beyond lost_contradiction, the robot is lost; beyond doubt_contradiction only,
 * those scans are searched for over the whole map and the robot is lost when they fit clearly
 * elsewhere (a map that changed a little keeps the estimate). Beams short of the map's walls
 * never count. */
static void watch_fit(marie_component_t *c, loc_t *s, const double odom[3], const mcl_scan_t *scan, const mcl_fit_t *fit,
                      int64_t utime)
{
    s->last_judged = utime;
    marie_debug("fit: %d on walls, %d short, %d through: contradiction %.2f (%d running)", fit->hit, fit->shorter,
                fit->through, fit->contradiction, s->poor);
    if (s->q->lost_contradiction <= 0 || s->force_left > 0 || fit->contradiction <= s->q->doubt_contradiction) {
        /* Particles just spread (a restart, a new initial pose) fit poorly until the forced
         * updates pull them in: that is not being lost. */
        s->poor = 0;
        return;
    }
    if (s->poor++ == 0)
        reloc_cloud_reset(s->doubts, odom);
    reloc_cloud_add(s->doubts, odom, s->seek.mount, scan);
    if (s->poor < s->q->lost_checks)
        return;
    if (fit->contradiction > s->q->lost_contradiction) {
        declare_lost(c, s, odom, fit, utime);
    } else if ((double)(utime - s->last_doubt) / 1e6 >= s->q->doubt_every_s) {
        s->last_doubt = utime;
        if (fits_elsewhere(c, s, odom))
            declare_lost(c, s, odom, fit, utime);
        else
            s->poor = 0;
    }
}

static void seek_report(marie_component_t *c, loc_t *s, const seek_out_t *o, int64_t utime)
{
    double took = (double)(utime - s->lost_since) / 1e6;
    switch (o->event) {
    case SEEK_SEARCHED:
        marie_component_count(c, "relocalization_searches", 1);
        marie_info("search %lld: %d places, best at (%.2f, %.2f, %.2f) now, %.0f%% of the points on walls, "
                   "%.0f%% through them, evidence %.3f vs %.3f", (long long)s->seek.searches, o->nhyp, o->best_now[0],
                   o->best_now[1], o->best_now[2], 100 * o->best.hit, 100 * o->best.contradiction, o->best_total,
                   o->second_total);
        break;
    case SEEK_FOUND:
        marie_component_count(c, "relocalizations", 1);
        marie_component_set_degraded(c, false, "%s", "localized");
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "relocalized", "relocalized at (%.2f, %.2f, %.2f) after %.1f s "
                              "and %lld searches", o->best_now[0], o->best_now[1], o->best_now[2], took,
                              (long long)s->seek.searches);
        break;
    case SEEK_GAVE_UP:
        marie_component_count(c, "relocalizations_failed", 1);
        publish_search(c, utime, 0, 0);
        marie_component_set_degraded(c, true, "lost: cannot relocalize (%s); send a pose on %s", o->why,
                                     marie_port_channel(marie_port(c, "initialpose")));
        marie_component_heartbeat(c);       /* the operator reads the new reason now */
        marie_component_event(c, MARIE_EVENT_T_SEV_ERROR, "relocalization_failed", "after %.1f s and %lld searches: %s; "
                              "standing still, waiting for a pose on %s", took, (long long)s->seek.searches, o->why,
                              marie_port_channel(marie_port(c, "initialpose")));
        break;
    default:
        break;
    }
}

/* Lost: the search decides; true while no pose should be published (a wrong pose would steer
 * the robot; a stale one stops it). */
static bool seek_scan(marie_component_t *c, loc_t *s, const double odom[3], const mcl_scan_t *ms, int64_t utime)
{
    if (s->seek_at_start) {
        s->seek_at_start = false;
        s->lost_since = utime;
        seek_begin(&s->seek, odom, (double)utime / 1e6);
        marie_component_set_degraded(c, true, "lost: %s", seek_doing(&s->seek));
    }
    if (!seek_active(&s->seek))
        return false;
    seek_out_t o;
    seek_phase_t was = s->seek.phase;
    seek_step(&s->seek, s->f, odom, ms, (double)utime / 1e6, &o);
    if (o.update_filter && mcl_step(s->f, odom, ms, true))
        marie_component_count(c, "filter_updates", 1);
    if (o.move)
        publish_search(c, utime, o.v, o.omega);
    else if (s->seek.phase == SEEK_VERIFY)
        publish_search(c, utime, 0, 0);     /* stand still while the place found is checked */
    seek_report(c, s, &o, utime);
    if (s->seek.phase != was && s->seek.phase != SEEK_OFF && s->seek.phase != SEEK_ASK)
        marie_component_set_degraded(c, true, "lost: %s", seek_doing(&s->seek));
    return seek_active(&s->seek);
}

static void process(marie_component_t *c, loc_t *s, const marie_laser_scan_t *scan)
{
    double odom[3];
    if (!posebuf_at(&s->odom, scan->utime, odom))
        return;
    mcl_scan_t ms = { scan->ranges, scan->nranges, scan->angle_min, scan->angle_increment,
                      scan->range_min, scan->range_max };
    if ((double)(scan->utime - posebuf_newest(&s->odom)) / 1e6 > s->q->odom_timeout_s) {
        /* Without odometry the filter cannot follow the robot: publishing its frozen pose
         * would steer the robot blind. Stay silent so the pose goes stale downstream. */
        marie_component_count(c, "scans_stale_odometry", 1);
        return;
    }
    if (seek_scan(c, s, odom, &ms, scan->utime))
        return;
    bool force = s->force_left > 0;
    if (s->force_left > 0)
        s->force_left--;
    mcl_fit_t fit;
    if (mcl_step(s->f, odom, &ms, force)) {
        marie_component_count(c, "filter_updates", 1);
        mcl_last_fit(s->f, &fit, NULL, NULL);
        watch_fit(c, s, odom, &ms, &fit, scan->utime);
    } else if ((double)(scan->utime - s->last_judged) / 1e6 >= s->q->check_still_s) {
        /* Standing still the filter does not update; the scan is still checked. */
        double pose[3], cov[9];
        mcl_pose_at(s->f, odom, pose, cov);
        mcl_judge(s->f, pose, &ms, &fit);
        marie_component_count(c, "still_checks", 1);
        watch_fit(c, s, odom, &ms, &fit, scan->utime);
    }
    if (seek_active(&s->seek))
        return;
    marie_pose_cov_t out = { .utime = scan->utime, .frame = "map" };
    double pose[3];
    mcl_pose_at(s->f, odom, pose, out.cov);
    out.pose.x = pose[0];
    out.pose.y = pose[1];
    out.pose.theta = pose[2];
    marie_port_publish(marie_port(c, "pose"), &out);
    if (!s->first_pub_utime)
        s->first_pub_utime = out.utime ? out.utime : 1;
    if (s->cloud_period_us > 0 && scan->utime - s->last_cloud >= s->cloud_period_us) {
        s->last_cloud = scan->utime;
        publish_cloud(c, s, scan->utime);
    }
}

static bool scan_ok(marie_component_t *c, const marie_laser_scan_t *m)
{
    if (m->nranges <= 0 || m->nranges > 10000 || !isfinite(m->angle_min) || !isfinite(m->angle_increment) ||
        m->angle_increment == 0 || !(m->range_max > 0) || !isfinite(m->range_max) || !isfinite(m->range_min)) {
        marie_component_bad_input(c, "bad_scan", "laser scan with %d beams, increment %g, range_max %g",
                                  m->nranges, m->angle_increment, m->range_max);
        return false;
    }
    return true;
}

static void on_scan_at_odometry(marie_component_t *c, const marie_laser_scan_t *m)
{
    process(c, marie_component_user(c), m);
}

static void on_scan(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    loc_t *s = marie_component_user(c);
    const marie_laser_scan_t *m = msg;
    if (!scan_ok(c, m))
        return;
    scanwait_scan(&s->wait, c, &s->odom, m, on_scan_at_odometry);
}

static void on_odom(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    loc_t *s = marie_component_user(c);
    const marie_odometry_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_odometry", "odometry pose is not finite");
        return;
    }
    double jump;
    int64_t last_utime = posebuf_newest(&s->odom);
    bool restarted = posebuf_frame_changed(&s->odom, m, s->last_distance, &jump);
    s->last_distance = m->distance;
    if (restarted) {
        /* The robot moved unseen while the odometry was away. Downstream stops it once our
         * pose goes stale (we publish none without odometry): it went on with the velocity
         * the old odometry last reported (not the new one's first, which starts at rest) for
         * some part of at most 1 s. The particles are centred half way along that and spread
         * over all of it; the laser pulls them in. */
        double gap = fabs((double)(m->utime - last_utime)) / 1e6;
        double t = fmin(gap, 1.0), half = t / 2;
        double pose[3], cov[9];
        mcl_estimate(s->f, pose, cov);
        double h = pose[2] + 0.5 * s->last_omega * half;
        pose[0] += s->last_v * half * cos(h);
        pose[1] += s->last_v * half * sin(h);
        pose[2] += s->last_omega * half;
        double sig[3] = { 0.1 + (0.5 * fabs(s->last_v) + 0.15) * t, 0.1 + (0.5 * fabs(s->last_v) + 0.15) * t,
                          0.05 + (0.5 * fabs(s->last_omega) + 0.1) * t };
        mcl_init_pose(s->f, pose, sig);
        s->force_left = 10;
        marie_component_count(c, "odometry_restarts", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "odometry_restart",
                              "odometry frame jumped after %.1f s: particles spread by %.2f m, %.2f rad", gap, sig[0], sig[2]);
        posebuf_clear(&s->odom);
        scanwait_drop(&s->wait);
        s->seek_at_start = seek_active(&s->seek);   /* a search starts over in the new frame */
    }
    if (isfinite(m->v) && isfinite(m->omega) && fabs(m->v) < 10 && fabs(m->omega) < 10) {
        s->last_v = m->v;
        s->last_omega = m->omega;
    }
    posebuf_add(&s->odom, m->utime, (const double[3]){ m->pose.x, m->pose.y, m->pose.theta });
    scanwait_odometry(&s->wait, c, m->utime, on_scan_at_odometry);
}

/* A pose to start from: refused where the robot cannot stand (inside a wall, in unknown space,
 * off the map); it ends a search. */
static bool start_at(marie_component_t *c, loc_t *s, const double pose[3], const double sig[3], const char *from)
{
    mcl_place_t where = mcl_map_at(s->f, pose[0], pose[1]);
    if (where != MCL_FREE) {
        marie_component_bad_input(c, "bad_initialpose", "%s (%.2f, %.2f) is %s: not taken", from, pose[0], pose[1],
                                  mcl_place_name(where));
        return false;
    }
    mcl_init_pose(s->f, pose, sig);
    s->force_left = 10;
    s->poor = 0;
    s->seek_at_start = false;
    if (seek_active(&s->seek)) {
        seek_end(&s->seek);
        marie_component_set_degraded(c, false, "%s", "localized");
    }
    return true;
}

static void on_initialpose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    loc_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    double pose[3] = { m->pose.x, m->pose.y, m->pose.theta };
    double sig[3] = { sqrt(fmax(m->cov[0], 0.0025)), sqrt(fmax(m->cov[4], 0.0025)), sqrt(fmax(m->cov[8], 0.0025)) };
    if (!isfinite(pose[0]) || !isfinite(pose[1]) || !isfinite(pose[2]) || !isfinite(sig[0]) || !isfinite(sig[1]) ||
        !isfinite(sig[2])) {
        marie_component_bad_input(c, "bad_initialpose", "initial pose is not finite");
        return;
    }
    if (start_at(c, s, pose, sig, "initial pose"))
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "localizer_reset", "particles reset around (%.2f, %.2f, %.2f)",
                              pose[0], pose[1], pose[2]);
}

/* A restarted localizer continues from the last pose it published, kept by the POSE Mailbox. */
static void on_resume(marie_component_t *c, marie_port_t *p, int status, const void *msg, int64_t age_us, void *user)
{
    loc_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    if (status != 0 || !m || !s->f) {
        marie_info("no earlier pose to resume from (%s): starting from the configured one",
                   status == ENODATA ? "the Mailbox is empty" : status == ETIMEDOUT ? "no Mailbox answered" : "bad reply");
        return;
    }
    if (s->first_pub_utime && m->utime >= s->first_pub_utime) {
        marie_info("the Mailbox holds only this run's poses: nothing to resume");
        return;
    }
    if (age_us / 1e6 > s->q->resume_max_age_s || !isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta) ||
        strcmp(m->frame, "map") != 0) {
        marie_info("earlier pose is %.1f s old or unusable: starting from the configured one", age_us / 1e6);
        return;
    }
    double pose[3] = { m->pose.x, m->pose.y, m->pose.theta };
    double sig[3] = { 0.3, 0.3, 0.15 };
    if (!start_at(c, s, pose, sig, "the earlier pose"))
        return;
    marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "localizer_resumed",
                          "resumed at (%.2f, %.2f, %.2f), the last pose published %.1f s ago", pose[0], pose[1],
                          pose[2], age_us / 1e6);
}

static int start(marie_component_t *c)
{
    loc_t *s = marie_component_user(c);
    if (s->q->resume_max_age_s > 0 &&
        marie_port_pull_async(marie_port(c, "resume"), 300, on_resume, NULL) != 0)
        marie_component_count(c, "resume_pull_errors", 1);
    return 0;
}

static void quit(marie_component_t *c)
{
    loc_t *s = marie_component_user(c);
    MARIE_CLEAR(s->f, mcl_destroy);
    seek_free(&s->seek);
    MARIE_CLEAR(s->doubts, reloc_cloud_destroy);
    scanwait_free(&s->wait);
    MARIE_CLEAR(s->cloud_buf, free);
}

static int init(marie_component_t *c)
{
    loc_t *s = marie_component_user(c);
    quit(c);    /* init again after a failure starts from scratch */
    posebuf_clear(&s->odom);
    scanwait_drop(&s->wait);
    s->force_left = 0;
    s->last_distance = 0;
    const loc_params_t *q = s->q = marie_component_params(c);
    s->first_pub_utime = 0;
    s->poor = 0;
    s->seek_at_start = false;
    s->last_judged = INT64_MIN / 2;
    marie_component_set_degraded(c, false, "%s", "localized");
    marie_errors_t errs = { 0 };
    occmap_t *map = occmap_load(q->map, &errs);
    if (!map) {
        marie_component_fail_reason(c, "map: %s", errs.n ? errs.msgs[0] : "cannot load");
        marie_errors_clear(&errs);
        return -1;
    }
    marie_info("map %s: %d x %d cells at %.3f m", q->map, map->width, map->height, map->resolution);
    mcl_params_t p = q->mcl;
    if (!q->recovery) {
        p.alpha_slow = p.alpha_fast = 0;
    }
    s->f = mcl_create(map, &p, (uint64_t)q->seed);
    occmap_destroy(map);
    if (!s->f) {
        marie_component_fail_reason(c, "bad filter parameters (particles_min <= particles_max, sigma_hit > 0, max_beams >= 1)");
        return -1;
    }
    s->last_doubt = INT64_MIN / 2;
    s->doubts = reloc_cloud_create();
    if (!s->doubts || seek_init(&s->seek, &q->seek, (const double[3]){ p.laser_x, p.laser_y, p.laser_theta }) < 0) {
        marie_component_fail_reason(c, "out of memory");
        return -1;
    }
    if (strcmp(q->init_mode, "global") == 0) {
        mcl_init_global(s->f);
        s->seek_at_start = true;
    } else if (strcmp(q->init_mode, "pose") == 0) {
        double pose[3] = { q->init_x, q->init_y, q->init_theta };
        double sig[3] = { q->init_sigma_xy, q->init_sigma_xy, q->init_sigma_theta };
        mcl_place_t where = mcl_map_at(s->f, pose[0], pose[1]);
        if (where != MCL_FREE) {
            marie_component_fail_reason(c, "init_x, init_y: (%.2f, %.2f) is %s of %s: give a pose in its free space, "
                                        "or init_mode: global", pose[0], pose[1], mcl_place_name(where), q->map);
            return -1;
        }
        mcl_init_pose(s->f, pose, sig);
        s->force_left = 10;     /* the scans at start pull the particles in, moving or not */
    } else {
        marie_component_fail_reason(c, "init_mode: expected pose or global, got '%s'", q->init_mode);
        return -1;
    }
    s->cloud_period_us = q->cloud_hz > 0 ? 1e6 / q->cloud_hz : 0;
    s->cloud_buf = malloc(sizeof(float) * 4 * (size_t)cloud_max(q));
    s->last_cloud = INT64_MIN / 2;
    if (!s->cloud_buf)
        return -1;
    if (marie_port_on_message(marie_port(c, "odom"), on_odom) || marie_port_on_message(marie_port(c, "scan"), on_scan) ||
        marie_port_on_message(marie_port(c, "initialpose"), on_initialpose)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    return 0;
}

static const marie_port_spec_t ports[] = {
    { "odom", &marie_type_odometry_t, MARIE_IN, MARIE_PUSH, "ODOMETRY" },
    { "scan", &marie_type_laser_scan_t, MARIE_IN, MARIE_PUSH, "LASER" },
    { "initialpose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "INITIALPOSE" },
    { "pose", &marie_type_pose_cov_t, MARIE_OUT, MARIE_PUSH, "POSE" },
    { "particles", &marie_type_particle_cloud_t, MARIE_OUT, MARIE_PUSH, "PARTICLES" },
    { "search", &marie_type_motor_command_t, MARIE_OUT, MARIE_PUSH, "RELOCALIZE" },
    { "resume", &marie_type_pose_cov_t, MARIE_IN, MARIE_PULL, "POSE" },
    { 0 },
};

static const marie_param_spec_t params[] = LOC_PARAMS;

static const marie_component_def_t def = {
    .kind = "localizer", .ports = ports, .params = params, .params_size = sizeof(loc_params_t),
    .on_init = init, .on_start = start, .on_quit = quit,
};

int main(int argc, char **argv)
{
    loc_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
