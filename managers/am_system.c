/* marie-am's system: loading and checking the system file, and what survives a restart of
 * the manager (the system that is up, moves, the children to end). */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <sodium.h>

#include "core/clear.h"
#include "core/file.h"
#include "core/log.h"
#include "core/procstat.h"
#include "managers/am.h"
#include "managers/progcheck.h"

size_t am_ncomps(const am_t *am) { return am->system.ncomps; }
comp_t *am_comp_at(const am_t *am, size_t i) { return &am->system.comps[i]; }
const marie_system_t *am_system(const am_t *am) { return am->system.sys; }
const char *am_system_hash(const am_t *am) { return am->system.sys ? am->system.hash : ""; }
const char *am_system_path(const am_t *am) { return am->system.path; }
uint64_t am_system_text_hash(const am_t *am) { return am->system.text_hash; }
const char *am_profile(const am_t *am) { return am->system.profile; }
bool am_is_up(const am_t *am) { return am->system.up; }

/* The path of the state file STATE_DIR/name in path[PATH_MAX]. */
static char *state_path(const am_t *am, const char *name, char path[PATH_MAX])
{
    snprintf(path, PATH_MAX, "%s/%s", am->env.state_dir, name);
    return path;
}

/* STATE_DIR/name opened with fopen's mode; NULL with errno. */
static FILE *state_open(const am_t *am, const char *name, const char *mode)
{
    char path[PATH_MAX];
    return fopen(state_path(am, name, path), mode);
}

/* The live children, so that a manager restarted after a crash can end the ones that
 * outlived it (a component that ignores SIGTERM survives PR_SET_PDEATHSIG). */
static void write_children(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->system.children_timer = NULL;
    char path[PATH_MAX], tmp[PATH_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", state_path(am, "children", path));
    FILE *f = fopen(tmp, "w");
    if (!f)
        return;
    for (size_t i = 0; i < am->system.ncomps; i++) {
        comp_t *c = &am->system.comps[i];
        if (c->sv.pid <= 0 || !c->sv.local)
            continue;
        /* read here, not at each spawn: a pid not yet reaped is still that process */
        if (c->start_ticks == 0)
            marie_proc_starttime(c->sv.pid, &c->start_ticks);
        fprintf(f, "%d %lld %s\n", (int)c->sv.pid, (long long)c->start_ticks, c->cfg->name);
    }
    if (fclose(f) == 0)
        rename(tmp, path);
}

/* Written once the loop has done what it is doing: a bring-up of 45 writes the file once, not
 * once per spawn with every child before it. */
void am_save_children(am_t *am)
{
    if (!am->system.children_timer)
        am->system.children_timer = marie_loop_add_wall_oneshot(am->env.loop, 0, write_children, am);
    if (!am->system.children_timer)
        write_children(am->env.loop, NULL, 0, am);
}

void am_children_add(comp_t *c)
{
    c->start_ticks = 0;         /* read when the children file is written */
    am_save_children(c->am);
}

void am_flush_children(am_t *am)
{
    if (!am->system.children_timer)
        return;
    marie_loop_remove_timer(am->env.loop, am->system.children_timer);
    write_children(am->env.loop, NULL, 0, am);
}

void am_kill_leftovers(am_t *am)
{
    FILE *f = state_open(am, "children", "r");
    if (!f)
        return;
    int pid;
    long long ticks;
    char name[128];
    while (fscanf(f, "%d %lld %127s", &pid, &ticks, name) == 3) {
        int64_t now_ticks;
        /* the same pid and start time: still that process, not a reused pid */
        if (pid > 1 && marie_proc_starttime(pid, &now_ticks) == 0 && now_ticks == ticks) {
            marie_warn("%s (pid %d) outlived the previous marie-am: SIGKILL to its process group", name, pid);
            kill(-pid, SIGKILL);
            kill(pid, SIGKILL);
        }
    }
    fclose(f);
    char path[PATH_MAX];
    unlink(state_path(am, "children", path));
}

static void comps_free(comp_t *comps, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        comp_t *c = &comps[i];
        am_comp_cancel_timer(c);
        am_comp_unboost(c);
        am_output_free(c);
        am_limits_comp_free(c);
    }
    free(comps);
}

void am_comps_free(am_t *am)
{
    comps_free(am->system.comps, am->system.ncomps);
    am->system.comps = NULL;
    am->system.ncomps = 0;
}

/* Replace path atomically (written beside it, then renamed); failures are silent. */
static void write_file_atomic(const char *path, const char *text, size_t len, mode_t mode)
{
    char tmp[PATH_MAX];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
    if (fd < 0)
        return;
    ssize_t w = write(fd, text, len);
    close(fd);
    if (w == (ssize_t)len)
        rename(tmp, path);
}

static void sha256_hex(const void *data, size_t len, const char *extra, char out[65])
{
    crypto_hash_sha256_state s;
    uint8_t h[32];
    crypto_hash_sha256_init(&s);
    crypto_hash_sha256_update(&s, data, len);
    if (extra)
        crypto_hash_sha256_update(&s, (const uint8_t *)extra, strlen(extra) + 1);
    crypto_hash_sha256_final(&s, h);
    sodium_bin2hex(out, 65, h, sizeof h);
}

/* Remembered across restarts of the manager: which system is up, and the moves. */
void am_save_up_state(am_t *am)
{
    char path[PATH_MAX];
    state_path(am, "up", path);
    if (!am->system.up || !am->system.sys) {
        unlink(path);
        return;
    }
    char *text = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&text, &len);
    if (!m)
        return;
    fprintf(m, "system %s\nprofile %s\n", am->system.path, am->system.profile ? am->system.profile : "");
    if (am_system_origin(am))
        fprintf(m, "origin %s\n", am_system_origin(am));
    for (size_t i = 0; i < am->system.ncomps; i++)
        if (strcmp(am->system.comps[i].host, marie_am_component_host(am->system.sys, am->system.comps[i].cfg, am->env.host)) != 0)
            fprintf(m, "move %s %s\n", am->system.comps[i].cfg->name, am->system.comps[i].host);
    fclose(m);
    write_file_atomic(path, text, len, 0644);
    free(text);
}

const char *am_system_origin(const am_t *am)
{
    const char *f = am->system.sys ? am->system.sys->file : NULL;
    return f && f[0] == '/' && am->system.path && strcmp(f, am->system.path) != 0 ? f : NULL;
}

bool am_host_known(am_t *am, const char *h)
{
    for (size_t i = 0; i < am->system.sys->nhosts; i++)
        if (strcmp(am->system.sys->hosts[i], h) == 0)
            return true;
    return false;
}

/* A system file read and checked, not yet loaded. */
struct am_loading {
    char *path, *profile;       /* profile NULL for none */
    char *text;                 /* the file as read (its hash) */
    size_t len;
    marie_system_t *sys;
    marie_am_settings_t set;
};

const marie_system_t *am_loading_system(const am_loading_t *l) { return l->sys; }

bool am_comp_carried(const comp_t *c, const marie_system_t *next)
{
    const marie_component_cfg_t *n = marie_system_component(next, c->cfg->name);
    return n && strcmp(marie_component_hash(n), marie_component_hash(c->cfg)) == 0 && !am_comp_timer_pending(c);
}

void am_loading_free(am_loading_t *l)
{
    if (!l)
        return;
    marie_system_destroy(l->sys);
    free(l->text);
    free(l->path);
    free(l->profile);
    free(l);
}

static am_loading_t *am_loading_open(const char *path, const char *origin, const char *profile, marie_errors_t *errs)
{
    am_loading_t *l = calloc(1, sizeof *l);
    if (!l || !(l->path = strdup(path)) || (profile && *profile && !(l->profile = strdup(profile)))) {
        marie_errors_add(errs, path, 0, 0, "out of memory");
        am_loading_free(l);
        return NULL;
    }
    if (!(l->text = marie_file_read(path, MARIE_AM_SYSTEM_MAX_BYTES, &l->len))) {
        marie_errors_add(errs, path, 0, 0, "%s", strerror(errno));
        am_loading_free(l);
        return NULL;
    }
    l->sys = marie_system_load_text(origin && *origin ? origin : path, l->text, l->len, l->profile, errs);
    marie_yaml_unload();        /* the next system file is orders away, if it ever comes */
    if (!l->sys || marie_am_check_system(l->sys, &l->set, errs) < 0) {
        am_loading_free(l);
        return NULL;
    }
    return l;
}

/* The programs of this host's components exist and accept their entries (descriptions
 * cached in STATE_DIR/describe). */
static int check_programs(am_t *am, const am_loading_t *l, marie_errors_t *errs, bool *must_run)
{
    char *cache = NULL;
    if (asprintf(&cache, "%s/describe", am->env.state_dir) < 0)
        cache = NULL;
    marie_progcheck_t *p = marie_progcheck_create(am->env.self_dir, cache);
    free(cache);
    if (p && must_run)
        marie_progcheck_cached_only(p);
    int rc = p ? marie_progcheck_system(p, l->sys, am->env.host, am->env.host, errs) : -1;
    if (must_run)
        *must_run = !p || marie_progcheck_must_run(p);
    marie_progcheck_destroy(p);
    return rc;
}

int am_loading_check_programs(am_t *am, const am_loading_t *l, marie_errors_t *errs)
{
    return check_programs(am, l, errs, NULL);
}

int am_loading_check_cached(am_t *am, const am_loading_t *l, marie_errors_t *errs, bool *must_run)
{
    return check_programs(am, l, errs, must_run);
}

bool am_system_is(const am_t *am, const char *text, const char *profile)
{
    char hash[65];
    sha256_hex(text, strlen(text), profile, hash);
    return am->system.sys && strcmp(hash, am->system.hash) == 0;
}

am_loading_t *am_loading_sent(am_t *am, const char *text, const char *sender_path, const char *profile,
                              marie_errors_t *errs)
{
    /* Use the sender's file where this host sees the same text (relative paths in it keep
     * working); otherwise keep a copy in the state directory. */
    char path[PATH_MAX];
    size_t len = 0;
    char *local = sender_path[0] ? marie_file_read(sender_path, MARIE_AM_SYSTEM_MAX_BYTES, &len) : NULL;
    const char *origin = NULL;
    if (local && len == strlen(text) && memcmp(local, text, len) == 0) {
        snprintf(path, sizeof path, "%s", sender_path);
    } else {
        snprintf(path, sizeof path, "%s/system.yaml", am->env.state_dir);
        write_file_atomic(path, text, strlen(text), 0644);
        origin = sender_path;
    }
    free(local);
    return am_loading_open(path, origin, profile, errs);
}

int am_load_system(am_t *am, const char *path, const char *origin, const char *profile, marie_errors_t *errs)
{
    am_loading_t *l = am_loading_open(path, origin, profile, errs);
    if (!l || am_loading_check_programs(am, l, errs) < 0) {
        am_loading_free(l);
        return -1;
    }
    am_loading_install(am, l);
    return 0;
}

/* The system file's manager settings, where the command line gave none. */
static void apply_settings(am_t *am, const marie_am_settings_t *set)
{
    const am_opts_t *o = &am->env.opt;
    am_status_set_hz(am, o->given_status_hz ? o->status_hz : set->status_hz);
    am->system.log_rate = o->given_log_rate ? o->log_rate : set->log_rate;
    am->system.log_max_bytes = o->given_log_max ? o->log_max_bytes : set->log_max_bytes;
    am->system.log_keep = o->given_log_keep ? o->log_keep : set->log_keep;
}

void am_loading_install(am_t *am, am_loading_t *l)
{
    const marie_am_settings_t set = l->set;
    marie_system_t *sys = l->sys;
    l->sys = NULL;
    apply_settings(am, &set);
    comp_t *old = am->system.comps;
    size_t nold = am->system.ncomps;
    marie_system_t *old_sys = am->system.sys;
    am->system.sys = sys;
    am_balance_install(am, sys, &set.balance);
    sha256_hex(l->text, l->len, l->profile ? l->profile : "", am->system.hash);
    am->system.text_hash = marie_text_hash(l->text, l->len);
    free(am->system.path);
    am->system.path = realpath(l->path, NULL);
    if (!am->system.path)
        am->system.path = strdup(l->path);
    free(am->system.profile);
    am->system.profile = l->profile;
    l->profile = NULL;
    am_loading_free(l);
    am->system.comps = calloc(sys->ncomponents ? sys->ncomponents : 1, sizeof *am->system.comps);
    am->system.ncomps = sys->ncomponents;
    char logdir[PATH_MAX];
    snprintf(logdir, sizeof logdir, "%s/logs", am->env.state_dir);
    mkdir(logdir, 0755);
    snprintf(logdir, sizeof logdir, "%s/run", am->env.state_dir);
    mkdir(logdir, 0755);
    for (size_t i = 0; i < sys->ncomponents; i++) {
        comp_t *c = &am->system.comps[i];
        c->am = am;
        c->cfg = &sys->components[i];
        snprintf(c->host, sizeof c->host, "%s", marie_am_component_host(sys, c->cfg, am->env.host));
        marie_sv_init(&c->sv, c->cfg, strcmp(c->host, am->env.host) == 0);
        am_output_init(c);
        const marie_component_cfg_t *was = old_sys ? marie_system_component(old_sys, c->cfg->name) : NULL;
        if (was && am_comp_carried(&old[was - old_sys->components], sys))
            am_comp_carry(c, &old[was - old_sys->components]);
        am_output_set_rate(c, am->system.log_rate);
    }
    comps_free(old, nold);
    marie_system_destroy(old_sys);
    am_status_changed(am);
}

void am_log_settings(const am_t *am, int64_t *max_bytes, int *keep)
{
    *max_bytes = am->system.log_max_bytes;
    *keep = am->system.log_keep;
}

/* The effective configuration of every component this host runs, for comparing runs
 * (sim against robot): logged, and kept in the state directory. */
static void record_hashes(am_t *am)
{
    FILE *f = state_open(am, "config-hashes", "w");
    for (size_t i = 0; i < am->system.ncomps; i++) {
        const comp_t *c = &am->system.comps[i];
        if (!c->sv.local)
            continue;
        marie_info("%s: configuration %s", c->cfg->name, marie_component_hash(c->cfg));
        if (f)
            fprintf(f, "%s %s %s\n", c->cfg->name, marie_component_hash(c->cfg), am->system.profile ? am->system.profile : "-");
    }
    if (f)
        fclose(f);
}

void am_down(am_t *am)
{
    am->system.up = false;
    am_save_up_state(am);
}

void am_system_free(am_t *am)
{
    if (am->system.up_timer)
        marie_loop_remove_timer(am->env.loop, am->system.up_timer);
    am->system.up_timer = NULL;
    am_comps_free(am);
    MARIE_CLEAR(am->system.sys, marie_system_destroy);
    MARIE_CLEAR(am->system.path, free);
    MARIE_CLEAR(am->system.profile, free);
}

/* What an up order leaves for after its first spawns (am_up): the configuration hashes (the
 * log and the state directory) and the log files of the components still waiting (a spawn opens
 * its own). Done while the first ones start, not before: 45 hashes and 45 new files were 2-3 ms
 * of the manager's CPU between the order and the first spawn, each millisecond of it a chance
 * for other work to take the CPU for a whole time slice. */
static void up_settle(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->system.up_timer = NULL;
    if (!am->system.up)
        return;
    record_hashes(am);
    for (size_t i = 0; i < am->system.ncomps; i++)
        am_comp_open_log(&am->system.comps[i]);
}

void am_up(am_t *am)
{
    am->system.up = true;
    for (size_t i = 0; i < am->system.ncomps; i++)
        if (am->system.comps[i].sv.local)
            am_comp_want(&am->system.comps[i]);
    am_save_up_state(am);
    am_try_start_waiting(am);
    if (!am->system.up_timer && !(am->system.up_timer = marie_loop_add_wall_oneshot(am->env.loop, 0, up_settle, am)))
        up_settle(am->env.loop, NULL, 0, am);
}

void am_apply_move(am_t *am, comp_t *c, const char *host)
{
    am_balance_placed(am, c->cfg->name, host);
    if (strcmp(c->host, host) == 0)
        return;     /* placed where it runs: the same instance, watched as before */
    bool was_local = c->sv.local;
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    snprintf(c->host, sizeof c->host, "%s", host);
    marie_sv_set_local(&c->sv, strcmp(host, am->env.host) == 0, am->system.up, &act);
    if (!was_local && c->sv.local)
        am_comp_open_log(c);
    am_comp_apply(c, before, &act);
}

void am_restore_up_state(am_t *am)
{
    FILE *f = state_open(am, "up", "r");
    if (!f)
        return;
    char line[PATH_MAX + 64], sys[PATH_MAX] = "", origin[PATH_MAX] = "", profile[128] = "";
    char moves[64][2][128];
    int nmoves = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = 0;
        if (strncmp(line, "system ", 7) == 0)
            snprintf(sys, sizeof sys, "%.*s", (int)sizeof sys - 1, line + 7);
        else if (strncmp(line, "origin ", 7) == 0)
            snprintf(origin, sizeof origin, "%.*s", (int)sizeof origin - 1, line + 7);
        else if (strncmp(line, "profile ", 8) == 0)
            snprintf(profile, sizeof profile, "%.*s", (int)sizeof profile - 1, line + 8);
        else if (nmoves < 64 && sscanf(line, "move %127s %127s", moves[nmoves][0], moves[nmoves][1]) == 2)
            nmoves++;
    }
    fclose(f);
    if (!sys[0])
        return;
    marie_errors_t errs = {0};
    if (am_load_system(am, sys, origin, profile, &errs) < 0) {
        marie_error("cannot restore the system that was up (%s):", sys);
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        return;
    }
    for (int i = 0; i < nmoves; i++) {
        comp_t *c = am_comp_find(am, moves[i][0]);
        if (c && am_host_known(am, moves[i][1]))
            am_apply_move(am, c, moves[i][1]);
    }
    marie_info("restoring system %s (profile %s)", sys, profile[0] ? profile : "none");
    am_balance_up_when_placed(am);
}
