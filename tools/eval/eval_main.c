/* marie-eval: drives N random reachable goals in each world, headless and faster than real time,
 * and reports success, collisions, time and path length against the shortest path, localization
 * RMS, recoveries and relocalizations per world (the BARN benchmark's idea for marie). A world is
 * one of the evaluation worlds or any map_server map (--map), and may be made harder: obstacles
 * the map lacks, the robot carried away, a coarser map. */
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/cli.h"
#include "core/version.h"
#include "tools/eval/eval.h"

/* The evaluation worlds (sim/mkworld.py --eval) and their robot: Spartacus (0.3 m radius, 0.4 m
 * track, 0.1 m wheels) except in the maze, whose 0.8 m corridors are for the small robot of
 * config/small-robot.yaml. */
static const eval_world_t named[] = {
    { "office", "", 0.3, 0.1, 0.4, 0.1 },    { "maze", "", 0.18, 0.06, 0.26, 0.05 }, { "warehouse", "", 0.3, 0.1, 0.4, 0.1 },
    { "hall", "", 0.3, 0.1, 0.4, 0.1 },      { "cluttered", "", 0.3, 0.1, 0.4, 0.1 }, { "rotated", "", 0.3, 0.1, 0.4, 0.1 },
    { "fine", "", 0.3, 0.1, 0.4, 0.1 },      { "coarse", "", 0.3, 0.1, 0.4, 0.1 },
};
#define NNAMED (int)(sizeof named / sizeof named[0])
#define MAXWORLDS 64

typedef struct {
    const char *worlds_dir, *world, *maps, *format;
    double radius, clearance, track, wheel;
} args_t;

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

/* The next name of a comma-separated list into out; false at its end. */
static bool next_item(const char **list, char *out, size_t len)
{
    if (!*list || !**list)
        return false;
    const char *comma = strchr(*list, ',');
    size_t n = comma ? (size_t)(comma - *list) : strlen(*list);
    snprintf(out, len, "%.*s", (int)n, *list);
    *list = comma ? comma + 1 : *list + n;
    return true;
}

/* A map's row name: its file's stem ("depot" for .../depot.yaml), or the folder's name and the stem
 * ("nav2-warehouse") when an evaluation world or an earlier row has that name. */
static void map_name(const char *path, const eval_world_t *before, int n, char *out, size_t len)
{
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path, *dot = strstr(base, ".yaml");
    int stem = (int)(dot ? dot - base : (long)strlen(base));
    snprintf(out, len, "%.*s", stem, base);
    bool taken = false;
    for (int i = 0; i < NNAMED; i++)
        taken |= strcmp(named[i].name, out) == 0;
    for (int i = 0; i < n; i++)
        taken |= strcmp(before[i].name, out) == 0;
    const char *dir = base > path ? base - 1 : NULL, *from = dir;
    while (from && from > path && from[-1] != '/')
        from--;
    if (taken && dir && dir > from)
        snprintf(out, len, "%.*s-%.*s", (int)(dir - from), from, stem, base);
}

/* The worlds asked for: named ones (each checked), then maps. The count, or -1 (said why). */
static int collect(const args_t *a, eval_world_t *out)
{
    int n = 0;
    char item[512];
    const char *list = a->world ? a->world : a->maps ? "" : "office,maze,warehouse,hall,cluttered,rotated,fine,coarse";
    while (n < MAXWORLDS && next_item(&list, item, 64)) {
        int i = 0;
        while (i < NNAMED && strcmp(named[i].name, item) != 0)
            i++;
        if (i == NNAMED) {
            fprintf(stderr, "marie-eval: --world: no evaluation world '%s' (there are office, maze, warehouse, hall, "
                            "cluttered, rotated, fine, coarse; --map FILE.yaml takes any map_server map)\n", item);
            return -1;
        }
        out[n] = named[i];
        snprintf(out[n].yaml, sizeof out[n].yaml, "%s/%s.yaml", a->worlds_dir, item);
        if (access(out[n].yaml, R_OK) != 0) {
            fprintf(stderr, "marie-eval: %s: no such file (the evaluation worlds are made by `python3 sim/mkworld.py "
                            "--eval %s`, or make)\n", out[n].yaml, a->worlds_dir);
            return -1;
        }
        n++;
    }
    list = a->maps;
    while (n < MAXWORLDS && next_item(&list, item, sizeof item)) {
        eval_world_t w = { "", "", a->radius, a->clearance, a->track, a->wheel };
        map_name(item, out, n, w.name, sizeof w.name);
        snprintf(w.yaml, sizeof w.yaml, "%s", item);
        if (access(w.yaml, R_OK) != 0) {
            fprintf(stderr, "marie-eval: --map: %s: cannot read it\n", item);
            return -1;
        }
        out[n++] = w;
    }
    return n;
}

static void tag(eval_opts_t *o)
{
    char *t = o->tag;
    size_t len = sizeof o->tag;
    int k = 0;
    if (o->boxes)
        k += snprintf(t + k, len - k, "+boxes%lld", (long long)o->boxes);
    if (o->walls)
        k += snprintf(t + k, len - k, "+walls%lld", (long long)o->walls);
    if (o->kidnap)
        k += snprintf(t + k, len - k, "+kidnap%lld", (long long)o->kidnap);
    if (o->coarse > 0)
        snprintf(t + k, len - k, "+coarse%g", o->coarse);
}

static void print_tsv(const char *name, const char *tg, const eval_result_t *r, double mt, double mr)
{
    const struct { const char *what, *unit; double v; const char *fmt; } rows[] = {
        { "success", "%", r->tried ? 100.0 * r->reached / r->tried : 0, "%.0f" },
        { "collisions", "count", (double)r->collisions, "%.0f" },
        { "median_time", "s", mt, "%.1f" },
        { "median_path_over_shortest", "x", mr, "%.2f" },
        { "loc_rms", "m", r->rms, "%.3f" },
        { "recoveries", "count", (double)r->recoveries, "%.0f" },
        { "lost", "count", (double)r->lost, "%.0f" },
        { "relocalized", "count", (double)r->found, "%.0f" },
        { "asked_for_a_pose", "count", (double)r->asked, "%.0f" },
        { "goals_refused", "count", (double)r->refused, "%.0f" },
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        printf("eval\t%s%s_%s\t", name, tg, rows[i].what);
        printf(rows[i].fmt, rows[i].v);
        printf("\t%s\t\t\n", rows[i].unit);
    }
}

/* Every world in turn, its row printed (a table at the end, or TSV rows as they come). 0, 1 when
 * a world could not be run or a signal ended the runs. */
static int run_worlds(const eval_opts_t *o, const eval_world_t *worlds, int nw)
{
    int status = 0, done = 0;
    static char table[MAXWORLDS][200];
    for (int i = 0; i < nw && !eval_stopped(); i++, done++) {
        eval_rng_seed((uint64_t)o->seed * 1000003ull + (uint64_t)i);
        eval_result_t r;
        if (eval_run(o, &worlds[i], &r) < 0)
            status = 1;
        double mt = median(r.time_s, r.nres), mr = median(r.ratio, r.nratio);
        if (o->tsv)
            print_tsv(worlds[i].name, o->tag, &r, mt, mr);
        else
            snprintf(table[i], sizeof table[0], "%-16.40s %3d/%-3d %5.0f%% %5lld %7.1f %9.2f %8.3f %6lld %5lld %6lld %6lld %7lld",
                     worlds[i].name, r.reached, r.tried, r.tried ? 100.0 * r.reached / r.tried : 0,
                     (long long)r.collisions, mt, mr, r.rms, (long long)r.recoveries, (long long)r.lost,
                     (long long)r.found, (long long)r.asked, (long long)r.refused);
        fflush(stdout);
        free(r.time_s);
        free(r.ratio);
    }
    if (!o->tsv) {
        printf("%s%s\n%-16s %7s %6s %5s %7s %9s %8s %6s %5s %6s %6s %7s\n", o->tag[0] ? "worlds " : "", o->tag, "world",
               "goals", "succ", "coll", "time_s", "path/sh", "loc_rms", "recov", "lost", "found", "asked", "refused");
        for (int i = 0; i < done; i++)
            printf("%s\n", table[i]);
    }
    return eval_stopped() ? 1 : status;
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-eval", argc, argv);
    const char *b = getenv("B") ? getenv("B") : "build";
    static char dir[512], bin[PATH_MAX], out[512];
    snprintf(dir, sizeof dir, "%s/worlds/eval", b);
    snprintf(out, sizeof out, "%s/eval", b);
    ssize_t n = readlink("/proc/self/exe", bin, sizeof bin - 1);     /* the programs beside this one */
    if (n <= 0)
        return 1;
    bin[n] = 0;
    *strrchr(bin, '/') = 0;
    args_t a = { .worlds_dir = dir, .format = "table", .radius = 0.3, .clearance = 0.1, .track = 0.4, .wheel = 0.1 };
    eval_opts_t o = { .bin = bin, .out = out, .goals = 5, .seed = 1, .speed = 3, .tolerance = 0.4 };
    const marie_cli_opt_t opts[] = {
        { "world", MARIE_CLI_STRING, &a.world, 0, 0, "NAME[,NAME...] evaluation worlds (default: all eight, unless --map)" },
        { "worlds", MARIE_CLI_STRING, &a.worlds_dir, 0, 0, "DIR where the evaluation worlds are (default $B/worlds/eval)" },
        { "map", MARIE_CLI_STRING, &a.maps, 0, 0, "FILE.yaml[,FILE.yaml...] any map_server maps, driven by the robot below" },
        { "radius", MARIE_CLI_DOUBLE, &a.radius, 0.05, 2, "M the --map robot's radius (0.3)" },
        { "clearance", MARIE_CLI_DOUBLE, &a.clearance, 0, 1, "M the margin it keeps beyond it (0.1)" },
        { "track", MARIE_CLI_DOUBLE, &a.track, 0.05, 2, "M between its wheels (0.4)" },
        { "wheel", MARIE_CLI_DOUBLE, &a.wheel, 0.01, 1, "M its wheels' radius (0.1)" },
        { "boxes", MARIE_CLI_INT, &o.boxes, 0, 1000, "N boxes of 0.3-0.8 m the map lacks, where the robot drives" },
        { "walls", MARIE_CLI_INT, &o.walls, 0, 1000, "N wall segments of 1.5-4 m the map lacks" },
        { "kidnap", MARIE_CLI_INT, &o.kidnap, 0, 1000, "K carry the robot away 5 s into every K-th goal" },
        { "coarse", MARIE_CLI_DOUBLE, &o.coarse, 0, 1, "M give the robot the map at M m cells (the world stays)" },
        { "goals", MARIE_CLI_INT, &o.goals, 1, 1000, "N goals per world (5)" },
        { "seed", MARIE_CLI_INT, &o.seed, 0, 1e15, "S the same seed, the same worlds, starts and goals (1)" },
        { "speed", MARIE_CLI_DOUBLE, &o.speed, 0.1, 50, "X the simulator's speed over real time (3)" },
        { "out", MARIE_CLI_STRING, &o.out, 0, 0, "DIR the components' logs, per world (default $B/eval)" },
        { "format", MARIE_CLI_STRING, &a.format, 0, 0, "table or tsv (make bench's rows)" },
        { NULL, 0, NULL, 0, 0, NULL },
    };
    int rc = marie_cli_parse("marie-eval", opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (optind < argc || (strcmp(a.format, "table") && strcmp(a.format, "tsv"))) {
        fprintf(stderr, "marie-eval: %s\n", optind < argc ? "unexpected operand" : "--format: table or tsv");
        return 2;
    }
    o.tsv = strcmp(a.format, "tsv") == 0;
    tag(&o);
    static eval_world_t worlds[MAXWORLDS];
    int nw = collect(&a, worlds);
    if (nw <= 0)
        return nw < 0 ? 2 : (fprintf(stderr, "marie-eval: no world given\n"), 2);
    signal(SIGPIPE, SIG_IGN);
    return run_worlds(&o, worlds, nw);
}
