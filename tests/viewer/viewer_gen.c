/* viewer-gen: a synthetic mission for the viewer's tests and bench: map, true and estimated
 * poses, particles, laser, path, goals, arbitration records, events and heartbeats. It writes
 * an LCM log with LCM's own writer (lcm_eventlog), or publishes the same stream on the bus.
 *   viewer-gen log FILE [--seconds S] [--corrupt]
 *   viewer-gen live [--seconds S] [--speed X]          (default URL, LCM_DEFAULT_URL honoured) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>
#include <sys/stat.h>

#include <lcm/eventlog.h>
#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define W 400
#define H 300
#define RES 0.05

static int8_t cells[W * H];

typedef struct {
    lcm_eventlog_t *log;
    lcm_t *lcm;
    int64_t eventnum;
    int64_t utime;      /* time of the sample being written */
} out_t;

static void emit(out_t *o, const char *ch, const marie_type_t *t, const void *msg)
{
    int n = t->encoded_size(msg);
    void *buf = malloc((size_t)n);
    if (!buf || t->encode(buf, 0, n, msg) < 0) {
        free(buf);
        return;
    }
    if (o->log) {
        lcm_eventlog_event_t ev = {
            .eventnum = o->eventnum++, .timestamp = o->utime, .channellen = (int32_t)strlen(ch),
            .datalen = n, .channel = (char *)ch, .data = buf,
        };
        lcm_eventlog_write_event(o->log, &ev);
    } else {
        lcm_publish(o->lcm, ch, buf, (unsigned)n);
    }
    free(buf);
}

static void make_map(void)
{
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            int wall = i < 3 || j < 3 || i >= W - 3 || j >= H - 3;
            wall |= i >= 200 && i < 204 && (j < 120 || j > 170);      /* a wall with a door */
            wall |= j >= 200 && j < 204 && i > 260;                    /* a room in a corner */
            wall |= i >= 90 && i < 110 && j >= 60 && j < 80;           /* a pillar */
            cells[j * W + i] = wall ? 100 : 0;
        }
    for (int j = 250; j < 297; j++)                                    /* unknown patch */
        for (int i = 3; i < 40; i++)
            cells[j * W + i] = -1;
}

static int occupied(double x, double y)
{
    int i = (int)floor(x / RES), j = (int)floor(y / RES);
    if (i < 0 || j < 0 || i >= W || j >= H)
        return 1;
    return cells[j * W + i] == 100;
}

static float cast(double x, double y, double a, double rmax)
{
    for (double r = 0; r < rmax; r += RES / 2)
        if (occupied(x + r * cos(a), y + r * sin(a)))
            return (float)r;
    return (float)rmax;
}

static const double goals[][2] = {{4, 4}, {8, 7.2}, {17, 7.2}, {12, 9}, {12, 13}};
#define NGOALS 5

int main(int argc, char **argv)
{
    if (argc < 2 || (strcmp(argv[1], "log") && strcmp(argv[1], "live"))) {
        fprintf(stderr, "usage: viewer-gen log FILE [--seconds S] [--corrupt] [--truth TXT] | live [--seconds S] [--speed X]\n");
        return 2;
    }
    int live = strcmp(argv[1], "live") == 0;
    const char *file = NULL, *truth_file = NULL;
    double seconds = 45, speed = 1;
    int corrupt = 0;
    for (int i = 2; i < argc; i++) {
        if (strcmp(argv[i], "--seconds") == 0 && i + 1 < argc)
            seconds = atof(argv[++i]);
        else if (strcmp(argv[i], "--speed") == 0 && i + 1 < argc)
            speed = atof(argv[++i]);
        else if (strcmp(argv[i], "--truth") == 0 && i + 1 < argc)
            truth_file = argv[++i];
        else if (strcmp(argv[i], "--corrupt") == 0)
            corrupt = 1;
        else if (!file && !live)
            file = argv[i];
    }
    /* what the page must draw, written apart from the log so a test can find it on screen:
     * one line per 10 Hz sample, "ts x y th range0 ... range180" */
    FILE *truth_out = NULL;
    if (truth_file && !(truth_out = fopen(truth_file, "w"))) {
        fprintf(stderr, "viewer-gen: cannot write %s\n", truth_file);
        return 1;
    }
    out_t o = {0};
    if (live) {
        o.lcm = lcm_create(NULL);
        if (!o.lcm) {
            fprintf(stderr, "viewer-gen: cannot open LCM\n");
            return 1;
        }
    } else {
        if (!file || !(o.log = lcm_eventlog_create(file, "w"))) {
            fprintf(stderr, "viewer-gen: cannot write %s\n", file ? file : "(no file)");
            return 1;
        }
    }
    make_map();
    srand(7);
    const char *comps[] = {"sim", "localizer", "planner", "behaviours", "mission"};
    int pids[] = {4101, 4102, 4103, 4104, 4105};
    int64_t hbseq = 0, evseq = 0, cycle = 0;
    double x = 2, y = 3, th = 0.6, ex = 2, ey = 3, eth = 0.6;
    int goal = 0, goals_done = 0;
    int64_t t0 = live ? marie_wall_us() : 1763700000000000LL;
    int64_t start_mono = marie_mono_us();
    int steps = (int)(seconds * 50);             /* 50 Hz master tick */
    for (int k = 0; k <= steps; k++) {
        double ts = k / 50.0;
        if (live) {
            int64_t due = start_mono + (int64_t)(ts / speed * 1e6);
            int64_t now = marie_mono_us();
            if (due > now)
                usleep((useconds_t)(due - now));
            o.utime = marie_wall_us();
        } else {
            o.utime = t0 + (int64_t)(ts * 1e6);
        }
        if (k == 0 || (k % 250 == 0)) {          /* map every 5 s */
            marie_occupancy_grid_t g = {.utime = o.utime, .resolution = (float)RES, .width = W, .height = H,
                                        .origin = {0, 0, 0}, .ncells = W * H, .cells = cells};
            emit(&o, "MAP", &marie_type_occupancy_grid_t, &g);
        }
        /* motion towards the current goal (when the mission is not over) */
        double gx = goals[goal][0], gy = goals[goal][1];
        double dx = gx - x, dy = gy - y, dist = hypot(dx, dy);
        int estop = ts >= 12.0 && ts < 13.0;
        int near_wall = 0;
        if (k % 5 == 0 && goals_done < NGOALS && !estop) {
            double want = atan2(dy, dx), err = atan2(sin(want - th), cos(want - th));
            double v = dist > 0.3 ? 0.8 : 0, w = 2.0 * err;
            near_wall = occupied(x + 0.5 * cos(th), y + 0.5 * sin(th));
            if (near_wall)
                w = 1.5, v = 0.1;
            th += w * 0.1;
            x += v * cos(th) * 0.1;
            y += v * sin(th) * 0.1;
            if (occupied(x, y)) {               /* never inside a wall: step back */
                x -= v * cos(th) * 0.1;
                y -= v * sin(th) * 0.1;
            }
            ex = x + 0.05 * sin(ts * 1.3);
            ey = y + 0.04 * cos(ts * 0.7);
            eth = th + 0.02 * sin(ts);
        }
        if (k % 5 == 0) {                        /* 10 Hz: poses, laser */
            marie_pose_cov_t truth = {.utime = o.utime, .frame = "map", .pose = {x, y, th}};
            emit(&o, "SIM_TRUTH", &marie_type_pose_cov_t, &truth);
            marie_pose_cov_t est = {.utime = o.utime, .frame = "map", .pose = {ex, ey, eth},
                                    .cov = {0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.002}};
            emit(&o, "POSE", &marie_type_pose_cov_t, &est);
            float ranges[181];
            for (int b = 0; b < 181; b++)
                ranges[b] = cast(x, y, th - M_PI / 2 + b * M_PI / 180, 8.0);
            marie_laser_scan_t scan = {.utime = o.utime, .angle_min = (float)(-M_PI / 2),
                                       .angle_increment = (float)(M_PI / 180), .range_min = 0.05f,
                                       .range_max = 8.0f, .nranges = 181, .ranges = ranges};
            emit(&o, "LASER", &marie_type_laser_scan_t, &scan);
            if (truth_out) {
                fprintf(truth_out, "%.2f %.6f %.6f %.6f", ts, x, y, th);
                for (int b = 0; b < 181; b++)
                    fprintf(truth_out, " %.4f", ranges[b]);
                fputc('\n', truth_out);
            }
        }
        if (k % 25 == 0) {                       /* 2 Hz: particles */
            enum { NP = 300 };
            float px[NP], py[NP], pt[NP], pw[NP];
            for (int i = 0; i < NP; i++) {
                px[i] = (float)(ex + ((rand() % 1000) - 500) / 2500.0);
                py[i] = (float)(ey + ((rand() % 1000) - 500) / 2500.0);
                pt[i] = (float)eth;
                pw[i] = 1.0f / NP;
            }
            marie_particle_cloud_t pc = {.utime = o.utime, .frame = "map", .n = NP, .x = px, .y = py,
                                         .theta = pt, .weight = pw};
            emit(&o, "PARTICLES", &marie_type_particle_cloud_t, &pc);
        }
        if (k % 25 == 0) {                       /* 2 Hz: fiducial tags (one on the east wall) */
            marie_tag_detection_t tag = {.family = "tag36h11", .id = 7, .pose_valid = 1,
                                         .position = {0.2, 0, 19.5 - x}};
            marie_tag_detections_t td = {.utime = o.utime, .camera = "front", .frame = k / 25,
                                         .width = 640, .height = 480, .count = x > 13 ? 1 : 0, .tags = &tag};
            emit(&o, "TAG_DETECTIONS", &marie_type_tag_detections_t, &td);
        }
        if (k % 50 == 0 && goals_done < NGOALS) { /* 1 Hz: goal and path */
            marie_goal_t g = {.utime = o.utime, .id = goal + 1, .name = (char[16]){0},
                              .pose = {gx, gy, 0}, .tolerance = 0.3, .priority = NGOALS - goal};
            snprintf(g.name, 16, "room%d", goal + 1);
            emit(&o, "GOAL", &marie_type_goal_t, &g);
            marie_pose2d_t pts[3] = {{x, y, 0}, {(x + gx) / 2, (y + gy) / 2, 0}, {gx, gy, 0}};
            marie_path_t p = {.utime = o.utime, .goal_id = goal + 1, .status = 0, .nposes = 3, .poses = pts};
            emit(&o, "PATH", &marie_type_path_t, &p);
        }
        if (k % 10 == 0) {                       /* 5 Hz: the decision record */
            int follow = goals_done < NGOALS;
            marie_behaviour_vote_t votes[4] = {
                {"estop", 100, estop, 0, 0, estop ? "e-stop input pressed" : "released"},
                {"teleop", 50, 0, 0, 0, "no joystick"},
                {"avoid", 20, near_wall, 0.1, 1.5, near_wall ? "obstacle 0.5 m ahead" : "clear"},
                {"follow_path", 10, follow, 0.8, 0.0, follow ? "tracking path" : "no path"},
            };
            const char *winner = estop ? "estop" : near_wall ? "avoid" : follow ? "follow_path" : "none";
            marie_input_age_t ins[3] = {{"pose", 0.04}, {"path", 0.6}, {"scan", 0.05}};
            marie_arbitration_t a = {.utime = o.utime, .cycle = cycle++, .nvotes = 4, .votes = votes,
                                     .winner = (char *)winner, .v = estop ? 0 : 0.8, .omega = 0,
                                     .ninputs = 3, .inputs = ins};
            emit(&o, "ARBITRATION", &marie_type_arbitration_t, &a);
        }
        if (goals_done < NGOALS && dist < 0.3) {
            char text[64];
            snprintf(text, sizeof text, "goal %d (room%d) reached at %.1f s", goal + 1, goal + 1, ts);
            marie_event_t e = {.utime = o.utime, .source = "mission", .seq = ++evseq, .severity = 1,
                               .kind = "goal_reached", .text = text};
            emit(&o, "MARIE_EVENT", &marie_type_event_t, &e);
            goals_done++;
            goal = (goal + 1) % NGOALS;
        }
        if (k == (int)(12.0 * 50)) {
            marie_event_t e = {.utime = o.utime, .source = "behaviours", .seq = ++evseq, .severity = 2,
                               .kind = "estop", .text = "e-stop pressed"};
            emit(&o, "MARIE_EVENT", &marie_type_event_t, &e);
        }
        if (k % 50 == 0) {                       /* 1 Hz heartbeats; the planner restarts at 20 s */
            if (k == 20 * 50)
                pids[2] = 5203;
            for (int i = 0; i < 5; i++) {
                marie_heartbeat_t hb = {.utime = o.utime, .component = (char *)comps[i], .host = "pc1",
                                        .pid = pids[i], .seq = ++hbseq,
                                        .state = (i == 2 && k == 20 * 50) ? 1 : 2, .reason = "",
                                        .uptime_us = (int64_t)(ts * 1e6), .msgs_in = k, .msgs_out = k / 2};
                emit(&o, "MARIE_HEARTBEAT", &marie_type_heartbeat_t, &hb);
            }
        }
    }
    if (truth_out)
        fclose(truth_out);
    if (o.log) {
        lcm_eventlog_destroy(o.log);
        if (corrupt) {
            /* garbage in the middle, and the last record cut short */
            struct stat st;
            int fd = open(file, O_RDWR);
            if (fd < 0 || fstat(fd, &st) < 0)
                return 1;
            char junk[300];
            memset(junk, 0x5a, sizeof junk);
            if (pwrite(fd, junk, sizeof junk, st.st_size / 2) != (ssize_t)sizeof junk ||
                ftruncate(fd, st.st_size - 37) < 0)
                return 1;
            /* and the 4th record claims a 50 MB payload: plausible, but longer than the log */
            off_t off = 0;
            for (int i = 0; i < 3; i++) {
                unsigned char h[28];
                if (pread(fd, h, sizeof h, off) != (ssize_t)sizeof h)
                    return 1;
                uint32_t cl = (uint32_t)h[20] << 24 | h[21] << 16 | h[22] << 8 | h[23];
                uint32_t dl = (uint32_t)h[24] << 24 | h[25] << 16 | h[26] << 8 | h[27];
                off += 28 + cl + dl;
            }
            unsigned char big[4] = {0x03, 0x20, 0x00, 0x00};
            if (pwrite(fd, big, 4, off + 24) != 4)
                return 1;
            close(fd);
        }
    } else {
        lcm_destroy(o.lcm);
    }
    return 0;
}
