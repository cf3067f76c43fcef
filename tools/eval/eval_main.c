/* marie-eval: drives N random reachable goals in each evaluation world, headless and faster than
 * real time, and reports success, collisions, time and path length against the shortest path,
 * localization RMS and recoveries per world (the BARN benchmark's idea for marie). */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/loop.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "map/gridpath.h"
#include "map/occmap.h"
#include "core/version.h"

extern char **environ;

/* The robot for each world: Spartacus (0.3 m radius, 0.4 m track, 0.1 m wheels) except in the
 * maze, whose 0.8 m corridors are for the small robot of config/small-robot.yaml. */
typedef struct {
    const char *name;
    double radius, clearance, track, wheel;
} world_t;

static const world_t worlds[] = {
    { "office", 0.3, 0.1, 0.4, 0.1 },    { "maze", 0.18, 0.06, 0.26, 0.05 }, { "warehouse", 0.3, 0.1, 0.4, 0.1 },
    { "hall", 0.3, 0.1, 0.4, 0.1 },      { "cluttered", 0.3, 0.1, 0.4, 0.1 }, { "rotated", 0.3, 0.1, 0.4, 0.1 },
    { "fine", 0.3, 0.1, 0.4, 0.1 },      { "coarse", 0.3, 0.1, 0.4, 0.1 },
};
#define NWORLDS (int)(sizeof worlds / sizeof worlds[0])

typedef struct {
    const char *dir, *bin, *out, *only;
    int goals;
    uint64_t seed;
    double speed, tolerance;
    bool tsv;
} opts_t;

typedef struct {
    int64_t sim_us, truth_us;
    double truth[3];
    bool have_truth, have_pose;
    double err_sq;
    int64_t nerr;
    int64_t collisions, recoveries, kidnaps;
    /* the goal being driven to: the path is summed and the arrival seen per truth message */
    marie_goal_t goal;
    bool driving, reached;
    int64_t t0, limit_us;       /* sim time */
    double travelled;
    lcm_t *lcm;
} live_t;

typedef struct {
    int tried, reached;
    double *time_s, *ratio;     /* per reached goal */
    int nres;
    double rms;
    int64_t collisions, recoveries, kidnaps;
} result_t;

/* ---- random numbers (splitmix64): the same seed gives the same starts and goals ---- */
static uint64_t rng_state;
static uint64_t rng_next(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static double rng_unit(void) { return (double)(rng_next() >> 11) / 9007199254740992.0; }

/* ---- LCM ---- */
static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    live_t *L = user;
    if (!strcmp(ch, "SIM_TRUTH")) {
        marie_pose_cov_t m;
        if (marie_decode_checked(&marie_type_pose_cov_t, rb->data, rb->data_size, &m) < 0)
            return;
        if (L->driving) {
            L->travelled += hypot(m.pose.x - L->truth[0], m.pose.y - L->truth[1]);
            L->reached = hypot(m.pose.x - L->goal.pose.x, m.pose.y - L->goal.pose.y) < L->goal.tolerance;
            L->driving = !L->reached;
        }
        L->truth[0] = m.pose.x, L->truth[1] = m.pose.y, L->truth[2] = m.pose.theta;
        L->truth_us = L->sim_us = m.utime;
        L->have_truth = true;
        marie_pose_cov_t_decode_cleanup(&m);
    } else if (!strcmp(ch, "POSE")) {
        marie_pose_cov_t m;
        if (marie_decode_checked(&marie_type_pose_cov_t, rb->data, rb->data_size, &m) < 0)
            return;
        /* Against the newest truth (50 Hz: at 0.5 m/s at most 1 cm behind). */
        if (L->have_truth && llabs(m.utime - L->truth_us) < 100000) {
            double e = hypot(m.pose.x - L->truth[0], m.pose.y - L->truth[1]);
            L->err_sq += e * e;
            L->nerr++;
        }
        L->have_pose = true;
        marie_pose_cov_t_decode_cleanup(&m);
    } else if (!strcmp(ch, "MARIE_HEARTBEAT")) {
        marie_heartbeat_t hb;
        if (marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &hb) < 0)
            return;
        for (int i = 0; i < hb.ncounters; i++) {
            const char *n = hb.counters[i].name;
            int64_t v = hb.counters[i].value;
            if (!strcmp(hb.component, "sim") && !strcmp(n, "collisions"))
                L->collisions = v;
            else if (!strcmp(hb.component, "behaviours") && !strcmp(n, "recoveries"))
                L->recoveries = v;
            else if (!strcmp(hb.component, "localizer") && !strcmp(n, "kidnaps_detected"))
                L->kidnaps = v;
        }
        marie_heartbeat_t_decode_cleanup(&hb);
    }
}

static int live_ready(void *user) { return ((live_t *)user)->have_pose && ((live_t *)user)->have_truth; }

/* Reached, or out of simulated time. */
static int goal_over(void *user)
{
    live_t *L = user;
    return L->reached || L->sim_us - L->t0 >= L->limit_us;
}

/* Repeated, as the mission does. */
static void publish_goal(live_t *L)
{
    L->goal.utime = L->sim_us;
    marie_goal_t_publish(L->lcm, "GOAL", &L->goal);
}

static void on_goal_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user) { publish_goal(user); }

/* ---- processes ---- */
static pid_t spawn(const opts_t *o, const char *log, char *const argv[])
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid = -1;
    if (posix_spawn(&pid, argv[0], &fa, NULL, argv, environ) != 0)
        pid = -1;
    posix_spawn_file_actions_destroy(&fa);
    return pid;
}

static void stop_all(pid_t *pids, int n)
{
    for (int i = 0; i < n; i++)
        if (pids[i] > 0)
            kill(pids[i], SIGTERM);
    int64_t end = marie_mono_us() + 5000000;
    for (int i = 0; i < n; i++) {
        while (pids[i] > 0 && waitpid(pids[i], NULL, WNOHANG) == 0) {
            if (marie_mono_us() > end) {
                kill(pids[i], SIGKILL);
                waitpid(pids[i], NULL, 0);
                break;
            }
            usleep(20000);
        }
        pids[i] = -1;
    }
}

/* ---- the map: where the robot's centre may be, and shortest paths ---- */
static uint8_t *passable(const occmap_t *m, double r)
{
    int w = m->width, h = m->height, rr = (int)ceil(r / m->resolution);
    uint8_t *free_ = malloc((size_t)w * h), *pass = calloc((size_t)w * h, 1);
    if (!free_ || !pass) {
        free(free_);
        free(pass);
        return NULL;
    }
    for (size_t i = 0; i < (size_t)w * h; i++)
        free_[i] = m->cells[i] == OCCMAP_FREE;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            bool ok = free_[(size_t)y * w + x];
            for (int dy = -rr; ok && dy <= rr; dy++)
                for (int dx = -rr; ok && dx <= rr; dx++) {
                    if ((dx * dx + dy * dy) * m->resolution * m->resolution > r * r)
                        continue;
                    int xx = x + dx, yy = y + dy;
                    ok = xx >= 0 && yy >= 0 && xx < w && yy < h && free_[(size_t)yy * w + xx];
                }
            pass[(size_t)y * w + x] = ok;
        }
    free(free_);
    return pass;
}

/* The passable cell nearest (x, y) within 1 m, or -1. */
static int nearest_pass(const occmap_t *m, const uint8_t *pass, double x, double y)
{
    int cx, cy;
    if (!occmap_cell(m, x, y, &cx, &cy))
        return -1;
    int best = -1, rmax = (int)ceil(1.0 / m->resolution);
    double bd = INFINITY;
    for (int dy = -rmax; dy <= rmax; dy++)
        for (int dx = -rmax; dx <= rmax; dx++) {
            int xx = cx + dx, yy = cy + dy;
            if (xx < 0 || yy < 0 || xx >= m->width || yy >= m->height || !pass[(size_t)yy * m->width + xx])
                continue;
            double d = dx * dx + dy * dy;
            if (d < bd) {
                bd = d;
                best = yy * m->width + xx;
            }
        }
    return best;
}

static int random_pass(const occmap_t *m, const uint8_t *pass)
{
    for (int k = 0; k < 100000; k++) {
        int c = (int)(rng_unit() * m->width * m->height);
        if (pass[c])
            return c;
    }
    return -1;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    if (n == 0)
        return NAN;
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

/* ---- one world ---- */
static int run_world(const opts_t *o, const world_t *wd, result_t *res)
{
    memset(res, 0, sizeof *res);
    char yaml[1024], dir[1024];
    snprintf(yaml, sizeof yaml, "%s/%s.yaml", o->dir, wd->name);
    snprintf(dir, sizeof dir, "%s/%s", o->out, wd->name);
    mkdir(o->out, 0755);
    mkdir(dir, 0755);
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(yaml, &errs);
    if (!m) {
        fprintf(stderr, "eval: %s: %s\n", yaml, errs.n ? errs.msgs[0] : "cannot load");
        marie_errors_clear(&errs);
        return -1;
    }
    /* Starts and goals keep a margin beyond the planner's inflation. */
    double r_plan = wd->radius + wd->clearance;
    uint8_t *pass = passable(m, r_plan + 0.05), *pass_path = passable(m, r_plan);
    res->time_s = calloc((size_t)o->goals + 1, sizeof(double));
    res->ratio = calloc((size_t)o->goals + 1, sizeof(double));
    if (!pass || !pass_path || !res->time_s || !res->ratio) {
        occmap_destroy(m);
        free(pass);
        free(pass_path);
        return -1;
    }
    int sc = random_pass(m, pass);
    if (sc < 0) {
        fprintf(stderr, "eval: %s: no free start\n", wd->name);
        occmap_destroy(m);
        free(pass);
        free(pass_path);
        return -1;
    }
    double sx, sy, sth = (rng_unit() * 2 - 1) * M_PI;
    occmap_cell_center(m, sc % m->width, sc / m->width, &sx, &sy);

    char a_world[1100], a_map[1100], a_sx[64], a_sy[64], a_sth[64], a_r[64], a_c[64], a_speed[64], a_seed[64],
        a_lx[64], a_ly[64], a_lth[64], a_tr[64], a_wr[64], prog[5][512], logs[5][1200];
    snprintf(a_tr, sizeof a_tr, "track=%g", wd->track);
    snprintf(a_wr, sizeof a_wr, "wheel_radius=%g", wd->wheel);
    snprintf(a_world, sizeof a_world, "world=%s", yaml);
    snprintf(a_map, sizeof a_map, "map=%s", yaml);
    snprintf(a_sx, sizeof a_sx, "start_x=%.3f", sx);
    snprintf(a_sy, sizeof a_sy, "start_y=%.3f", sy);
    snprintf(a_sth, sizeof a_sth, "start_theta=%.3f", sth);
    snprintf(a_lx, sizeof a_lx, "init_x=%.3f", sx);
    snprintf(a_ly, sizeof a_ly, "init_y=%.3f", sy);
    snprintf(a_lth, sizeof a_lth, "init_theta=%.3f", sth);
    snprintf(a_r, sizeof a_r, "robot_radius=%g", wd->radius);
    snprintf(a_c, sizeof a_c, "robot_clearance=%g", wd->clearance);
    snprintf(a_speed, sizeof a_speed, "speed=%g", o->speed);
    snprintf(a_seed, sizeof a_seed, "seed=%llu", (unsigned long long)(o->seed % 1000000 + 1));
    static const char *const names[5] = { "sim", "odometry", "localizer", "planner", "behaviours" };
    static const char *const progs[5] = { "marie-sim", "marie-odometry", "marie-localizer", "marie-planner",
                                          "marie-behaviours" };
    for (int i = 0; i < 5; i++) {
        snprintf(prog[i], sizeof prog[i], "%s/%s", o->bin, progs[i]);
        snprintf(logs[i], sizeof logs[i], "%s/%s.log", dir, names[i]);
    }
    char *sim_a[] = { prog[0], "--name", "sim", "--param", a_world, "--param", "mode=channel", "--param", a_speed,
                      "--param", a_sx, "--param", a_sy, "--param", a_sth, "--param", a_seed, "--param", a_r,
                      "--param", a_tr, "--param", a_wr, NULL };
    char *odo_a[] = { prog[1], "--name", "odometry", "--clock", "sim", "--param", a_tr, "--param", a_wr, NULL };
    char *loc_a[] = { prog[2], "--name", "localizer", "--clock", "sim", "--param", a_map, "--param", a_lx, "--param",
                      a_ly, "--param", a_lth, "--param", "resume_max_age_s=0", NULL };
    char *pln_a[] = { prog[3], "--name", "planner", "--clock", "sim", "--param", a_map, "--param", a_r, "--param", a_c,
                      NULL };
    char *beh_a[] = { prog[4], "--name", "behaviours", "--clock", "sim", "--param", "input_mode=subscribe", "--param",
                      a_r, "--param", a_c, NULL };
    char *const *argvs[5] = { sim_a, odo_a, loc_a, pln_a, beh_a };

    lcm_t *l = marie_bus_create(NULL);
    marie_loop_t *loop = marie_loop_create();
    live_t L = { .lcm = l };
    pid_t pids[5];
    for (int i = 0; i < 5; i++)
        pids[i] = spawn(o, logs[i], argvs[i]);
    int rc = -1;
    if (!l || !loop || marie_loop_add_bus(loop, l, 64) < 0)
        goto out;
    marie_bus_subscribe(l, "SIM_TRUTH", on_msg, &L);
    marie_bus_subscribe(l, "POSE", on_msg, &L);
    marie_bus_subscribe(l, "MARIE_HEARTBEAT", on_msg, &L);
    marie_loop_run_until(loop, 30000, live_ready, &L);
    if (!L.have_pose) {
        fprintf(stderr, "eval: %s: no pose within 30 s (see %s)\n", wd->name, dir);
        goto out;
    }
    for (int k = 1; k <= o->goals; k++) {
        /* A goal at least 2 m away that the robot can reach, with its shortest path length. */
        int from = nearest_pass(m, pass_path, L.truth[0], L.truth[1]), gc = -1;
        double shortest = -1;
        for (int t = 0; from >= 0 && t < 500 && shortest < 0; t++) {
            int c = random_pass(m, pass);
            double gx, gy;
            occmap_cell_center(m, c % m->width, c / m->width, &gx, &gy);
            if (hypot(gx - L.truth[0], gy - L.truth[1]) < 2.0)
                continue;
            int *cells = NULL, nc = 0;
            if (gridpath_find(m->width, m->height, pass_path, from, c, &cells, &nc) > 0) {
                /* The grid's 8 directions overstate it: straighten it first. */
                nc = gridpath_shortcut(m->width, m->height, pass_path, cells, nc);
                shortest = 0;
                for (int q = 0; q + 1 < nc; q++)
                    shortest += hypot(cells[q + 1] % m->width - cells[q] % m->width,
                                      cells[q + 1] / m->width - cells[q] / m->width) * m->resolution;
                gc = c;
            }
            free(cells);
        }
        if (gc < 0) {
            fprintf(stderr, "eval: %s: no reachable goal from (%.2f, %.2f)\n", wd->name, L.truth[0], L.truth[1]);
            break;
        }
        double gx, gy;
        occmap_cell_center(m, gc % m->width, gc / m->width, &gx, &gy);
        res->tried++;
        L.goal = (marie_goal_t){ .id = k, .name = "eval", .pose = { gx, gy, 0 }, .tolerance = o->tolerance,
                                 .priority = 1 };
        L.t0 = L.sim_us;
        L.limit_us = (int64_t)((60 + 4 * shortest / 0.5) * 1e6);
        L.travelled = 0;
        L.reached = false;
        L.driving = true;
        publish_goal(&L);
        marie_timer_t *repeat = marie_loop_add_wall_timer(loop, 1000000, on_goal_timer, &L);
        double wall_limit_s = (60 + 4 * shortest / 0.5) / o->speed * 3 + 20;
        marie_loop_run_until(loop, wall_limit_s > 86400 ? 86400000 : (int)(wall_limit_s * 1000), goal_over, &L);
        marie_loop_remove_timer(loop, repeat);
        L.driving = false;
        bool reached = L.reached;
        double travelled = L.travelled, dt = (L.sim_us - L.t0) / 1e6;
        if (reached) {
            res->time_s[res->nres] = dt;
            res->ratio[res->nres] = travelled / fmax(shortest - o->tolerance, 0.1);
            res->nres++;
            res->reached++;
        }
        if (!o->tsv)
            printf("eval: %-9s goal %2d/%d (%6.2f, %6.2f): %s in %5.1f s, %5.1f m driven, shortest %5.1f m, "
                   "robot at (%.2f, %.2f)\n", wd->name, k, o->goals, gx, gy, reached ? "reached" : "MISSED ", dt,
                   travelled, shortest, L.truth[0], L.truth[1]);
        fflush(stdout);
    }
    /* Last counters: a heartbeat or two more. */
    marie_loop_run_until(loop, 1500, NULL, NULL);
    rc = 0;
out:
    stop_all(pids, 5);
    res->rms = L.nerr ? sqrt(L.err_sq / L.nerr) : NAN;
    res->collisions = L.collisions;
    res->recoveries = L.recoveries;
    res->kidnaps = L.kidnaps;
    marie_loop_destroy(loop);
    if (l)
        marie_bus_destroy(l);
    occmap_destroy(m);
    free(pass);
    free(pass_path);
    return rc;
}

static void usage(FILE *f)
{
    fprintf(f, "usage: marie-eval [--worlds DIR] [--world NAME[,NAME...]] [--goals N] [--seed S] [--speed X]\n"
               "                  [--out DIR] [--tsv]\n"
               "Drives N random reachable goals in each world (default all of: office maze warehouse hall\n"
               "cluttered rotated fine coarse, made by `python3 sim/mkworld.py --eval DIR`), headless on the\n"
               "simulator's clock, and prints per world: success, collisions, median time and path length\n"
               "over the shortest path, localization RMS, recoveries. --tsv: bench rows.\n");
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-eval", argc, argv);
    const char *b = getenv("B") ? getenv("B") : "build";
    static char dir[512], bin[512], out[512];
    snprintf(dir, sizeof dir, "%s/worlds/eval", b);
    snprintf(out, sizeof out, "%s/eval", b);
    /* The programs beside this one. */
    ssize_t n = readlink("/proc/self/exe", bin, sizeof bin - 1);
    if (n <= 0)
        return 1;
    bin[n] = 0;
    *strrchr(bin, '/') = 0;
    opts_t o = { .dir = dir, .bin = bin, .out = out, .goals = 5, .seed = 1, .speed = 3, .tolerance = 0.4 };
    static const struct option lo[] = { { "worlds", required_argument, 0, 'w' }, { "world", required_argument, 0, 'W' },
                                        { "goals", required_argument, 0, 'g' },  { "seed", required_argument, 0, 's' },
                                        { "speed", required_argument, 0, 'x' },  { "out", required_argument, 0, 'o' },
                                        { "tsv", no_argument, 0, 't' },          { "help", no_argument, 0, 'h' },
                                        { 0, 0, 0, 0 } };
    int c;
    while ((c = getopt_long(argc, argv, "h", lo, NULL)) != -1) {
        switch (c) {
        case 'w': o.dir = optarg; break;
        case 'W': o.only = optarg; break;
        case 'g': o.goals = atoi(optarg); break;
        case 's': o.seed = strtoull(optarg, NULL, 10); break;
        case 'x': o.speed = atof(optarg); break;
        case 'o': o.out = optarg; break;
        case 't': o.tsv = true; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (o.goals < 1 || o.goals > 1000 || !(o.speed > 0 && o.speed <= 50)) {
        usage(stderr);
        return 2;
    }
    signal(SIGPIPE, SIG_IGN);
    int status = 0;
    char table[NWORLDS][160];
    int nrows = 0;
    for (int i = 0; i < NWORLDS; i++) {
        if (o.only) {
            const char *p = strstr(o.only, worlds[i].name);
            size_t ln = strlen(worlds[i].name);
            if (!p || (p != o.only && p[-1] != ',') || (p[ln] && p[ln] != ','))
                continue;
        }
        rng_state = o.seed * 1000003ull + (uint64_t)i;
        result_t r;
        if (run_world(&o, &worlds[i], &r) < 0)
            status = 1;
        double succ = r.tried ? 100.0 * r.reached / r.tried : 0;
        double mt = median(r.time_s, r.nres), mr = median(r.ratio, r.nres);
        if (o.tsv) {
            printf("eval\t%s_success\t%.0f\t%%\t\t\n", worlds[i].name, succ);
            printf("eval\t%s_collisions\t%lld\tcount\t\t\n", worlds[i].name, (long long)r.collisions);
            printf("eval\t%s_median_time\t%.1f\ts\t\t\n", worlds[i].name, mt);
            printf("eval\t%s_median_path_over_shortest\t%.2f\tx\t\t\n", worlds[i].name, mr);
            printf("eval\t%s_loc_rms\t%.3f\tm\t\t\n", worlds[i].name, r.rms);
            printf("eval\t%s_recoveries\t%lld\tcount\t\t\n", worlds[i].name, (long long)(r.recoveries + r.kidnaps));
        } else {
            snprintf(table[nrows++], sizeof table[0], "%-10s %2d/%-2d %7.0f%% %5lld %8.1f %10.2f %8.3f %6lld",
                     worlds[i].name, r.reached, r.tried, succ, (long long)r.collisions, mt, mr, r.rms,
                     (long long)(r.recoveries + r.kidnaps));
        }
        fflush(stdout);
        free(r.time_s);
        free(r.ratio);
    }
    if (!o.tsv && nrows) {
        printf("%-10s %5s %8s %5s %8s %10s %8s %6s\n", "world", "goals", "success", "coll", "time_s", "path/short",
               "loc_rms", "recov");
        for (int i = 0; i < nrows; i++)
            printf("%s\n", table[i]);
    }
    return status;
}
