/* progcheck: before a system starts, every component's program must exist, and its entry must
 * match the ports and parameters the program declares (PROG --describe, cached per binary). */
#include "managers/progcheck.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <sodium.h>

#include "core/buf.h"
#include "core/clear.h"
#include "core/loop.h"
#include "core/spec.h"

#define DESCRIBE_TIMEOUT_MS 5000
#define DESCRIBE_MAX (1 << 20)

/* sys_file's folder joined with a relative path. */
static char *beside_file(const char *sys_file, const char *name)
{
    const char *slash = sys_file ? strrchr(sys_file, '/') : NULL;
    char *out;
    if (asprintf(&out, "%.*s%s", slash ? (int)(slash - sys_file + 1) : 0, slash ? sys_file : "", name) < 0)
        return NULL;
    return out;
}

char *marie_am_resolve_exec(const char *self_dir, const char *sys_file, const char *name)
{
    if (name[0] == '/')
        return strdup(name);
    if (strchr(name, '/'))
        return beside_file(sys_file, name);
    const char *path = getenv("PATH");
    char *dirs;
    if (asprintf(&dirs, "%s:%s", self_dir ? self_dir : "", path ? path : "/usr/local/bin:/usr/bin:/bin") < 0)
        return NULL;
    char *found = NULL, *save = NULL;
    for (char *d = strtok_r(dirs, ":", &save); d && !found; d = strtok_r(NULL, ":", &save)) {
        char *cand;
        if (!*d || asprintf(&cand, "%s/%s", d, name) < 0)
            continue;
        struct stat st;
        if (stat(cand, &st) == 0 && S_ISREG(st.st_mode) && access(cand, X_OK) == 0)
            found = cand;
        else
            free(cand);
    }
    free(dirs);
    return found;
}

/* ---- the description cache: memory for this process, files in cache_dir across runs ---- */

typedef struct spec_entry {
    char key[65];               /* sha256 of path, identity and mtime of the binary, and args */
    marie_doc_t *doc;           /* NULL: not a marie component */
    struct spec_entry *next;
} spec_entry_t;

struct marie_progcheck {
    char *self_dir, *cache_dir;
    spec_entry_t *entries;
    int described;              /* programs actually run (the rest came from a cache) */
    bool cached_only;           /* a program to run with --describe fails the check: must_run */
    bool must_run;
    marie_buf_t key_in, last_in;    /* what cache_key hashes, now and for the last key */
    char last_key[65];
};

marie_progcheck_t *marie_progcheck_create(const char *self_dir, const char *cache_dir)
{
    marie_progcheck_t *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    marie_buf_init(&p->key_in, 0);
    marie_buf_init(&p->last_in, 0);
    p->self_dir = self_dir ? strdup(self_dir) : NULL;
    p->cache_dir = cache_dir ? strdup(cache_dir) : NULL;
    if ((self_dir && !p->self_dir) || (cache_dir && !p->cache_dir)) {
        marie_progcheck_destroy(p);
        return NULL;
    }
    if (p->cache_dir)
        mkdir(p->cache_dir, 0755);   /* absent or unwritable: only the memory cache */
    return p;
}

void marie_progcheck_destroy(marie_progcheck_t *p)
{
    if (!p)
        return;
    for (spec_entry_t *e = p->entries, *n; e; e = n) {
        n = e->next;
        marie_doc_destroy(e->doc);
        free(e);
    }
    marie_buf_free(&p->key_in);
    marie_buf_free(&p->last_in);
    free(p->self_dir);
    free(p->cache_dir);
    free(p);
}


void marie_progcheck_cached_only(marie_progcheck_t *p) { p->cached_only = true; }
bool marie_progcheck_must_run(const marie_progcheck_t *p) { return p->must_run; }

/* A Python script built on marie's Python package (python/marie): a python #! line, and the
 * package imported at the start of a line. */
static int is_python_component(const char *m, size_t len)
{
    const char *nl = memchr(m, '\n', len);
    if (len < 2 || m[0] != '#' || m[1] != '!' || !nl || !memmem(m, (size_t)(nl - m), "python", 6))
        return 0;
    for (const char *p = nl; p && p + 1 < m + len; p = memchr(p + 1, '\n', (size_t)(m + len - p - 1))) {
        size_t left = (size_t)(m + len - p - 1);
        if ((left >= 13 && memcmp(p + 1, "import marie\n", 13) == 0) || (left >= 11 && memcmp(p + 1, "from marie ", 11) == 0))
            return 1;
    }
    return 0;
}

/* Only programs built on libmarie (or marie's Python package) are run with --describe: anything
 * else (a script, a device tool) might do something on an unknown option. */
static int has_marker(const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) < 0 || st.st_size == 0) {
        if (fd >= 0)
            close(fd);
        return 0;
    }
    void *m = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (m == MAP_FAILED)
        return 0;
    int found = memmem(m, (size_t)st.st_size, MARIE_SPEC_MARKER, strlen(MARIE_SPEC_MARKER)) != NULL ||
                is_python_component(m, (size_t)st.st_size);
    munmap(m, (size_t)st.st_size);
    return found;
}

/* The child's stdout, read from a loop of its own. */
typedef struct {
    FILE *m;
    size_t got;
    int done;                   /* end of file, or a read error */
} describe_out_t;

static void on_describe_out(marie_loop_t *loop, int fd, short revents, void *user)
{
    describe_out_t *o = user;
    char buf[8192];
    ssize_t n = read(fd, buf, sizeof buf);
    if (n < 0 && (errno == EINTR || errno == EAGAIN))
        return;
    if (n <= 0) {
        o->done = 1;
        return;
    }
    if (o->m && o->got + (size_t)n <= DESCRIBE_MAX)
        fwrite(buf, 1, (size_t)n, o->m);
    o->got += (size_t)n;
}

static int describe_out_done(void *user) { return ((describe_out_t *)user)->done; }

/* Run PATH ARGS... --describe with the component's env added (it may need it to load at all);
 * its stdout (at most DESCRIBE_MAX) in *out. 0, or -1 with why. */
static int run_describe(const char *path, const marie_component_cfg_t *c, size_t nargs, char **out, size_t *len,
                        char *why, size_t whylen)
{
    char **args = c->args;
    int po[2];
    if (pipe2(po, O_CLOEXEC) < 0) {
        snprintf(why, whylen, "pipe: %s", strerror(errno));
        return -1;
    }
    char **argv = calloc(nargs + 3, sizeof *argv);
    if (!argv) {
        close(po[0]);
        close(po[1]);
        snprintf(why, whylen, "out of memory");
        return -1;
    }
    size_t na = 0;
    argv[na++] = (char *)path;
    for (size_t i = 0; i < nargs; i++)
        argv[na++] = args[i];
    argv[na++] = "--describe";
    extern char **environ;
    size_t ne = 0;
    while (environ[ne])
        ne++;
    char **envp = calloc(ne + c->nenv + 1, sizeof *envp);
    if (!envp) {
        free(argv);
        close(po[0]);
        close(po[1]);
        snprintf(why, whylen, "out of memory");
        return -1;
    }
    size_t n = 0;
    for (size_t i = 0; i < ne; i++) {
        bool overridden = false;    /* getenv finds the first entry: drop the ones c->env sets */
        for (size_t k = 0; k < c->nenv && !overridden; k++) {
            size_t kl = strcspn(c->env[k], "=");
            overridden = strncmp(environ[i], c->env[k], kl + 1) == 0;
        }
        if (!overridden)
            envp[n++] = environ[i];
    }
    if (c->nenv)
        memcpy(envp + n, c->env, c->nenv * sizeof *envp);
    pid_t pid = fork();
    if (pid == 0) {
        /* marie-am blocks its signals (signalfd): the program must not inherit that */
        sigset_t none;
        sigemptyset(&none);
        sigprocmask(SIG_SETMASK, &none, NULL);
        int nul = open("/dev/null", O_RDWR);
        dup2(nul, 0);
        dup2(po[1], 1);
        dup2(nul, 2);
        execve(path, argv, envp);
        _exit(127);
    }
    free(argv);
    free(envp);
    close(po[1]);
    if (pid < 0) {
        close(po[0]);
        snprintf(why, whylen, "fork: %s", strerror(errno));
        return -1;
    }
    describe_out_t o = { .m = open_memstream(out, len) };
    int rc = 0;
    marie_loop_t *loop = o.m ? marie_loop_create() : NULL;
    if (!loop || marie_loop_add_fd(loop, po[0], POLLIN, on_describe_out, &o) < 0) {
        snprintf(why, whylen, "out of memory");
        rc = -1;
    } else if (marie_loop_run_until(loop, DESCRIBE_TIMEOUT_MS, describe_out_done, &o) != 1) {
        snprintf(why, whylen, "no answer within %d s", DESCRIBE_TIMEOUT_MS / 1000);
        rc = -1;
    }
    marie_loop_destroy(loop);
    close(po[0]);
    if (o.m)
        fclose(o.m);
    if (rc < 0)
        kill(pid, SIGKILL);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (rc == 0 && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
        if (WIFEXITED(status))
            snprintf(why, whylen, "exit status %d", WEXITSTATUS(status));
        else
            snprintf(why, whylen, "killed by signal %d", WIFSIGNALED(status) ? WTERMSIG(status) : 0);
        rc = -1;
    }
    if (rc < 0) {
        free(*out);
        *out = NULL;
    }
    return rc;
}

/* The leading arguments that are not options choose what a program is (marie-ca mailbox);
 * options (--param, --port) are checked against the description instead. */
static size_t kind_args(const marie_component_cfg_t *c)
{
    size_t n = 0;
    while (n < c->nargs && c->args[n][0] != '-')
        n++;
    return n;
}

/* The cache's key: sha256 of the path, the binary's identity and mtime, and the kind's args.
 * A system names one program many times (45 marie-test-comp): the same bytes as the last
 * program's give its key again, without the hash (once most of a cached check's CPU). */
static void cache_key(marie_progcheck_t *p, const char *path, const struct stat *st, const marie_component_cfg_t *c,
                      char key[65])
{
    marie_buf_t *in = &p->key_in;
    marie_buf_reset(in);
    marie_buf_puts(in, path);
    marie_buf_printf(in, "%s\n%llu:%llu:%lld:%lld.%09ld\n", path, (unsigned long long)st->st_dev,
                     (unsigned long long)st->st_ino, (long long)st->st_size, (long long)st->st_mtim.tv_sec,
                     st->st_mtim.tv_nsec);
    for (size_t i = 0; i < kind_args(c); i++)
        marie_buf_put(in, c->args[i], strlen(c->args[i]) + 1);
    if (!in->failed && in->len == p->last_in.len && p->last_in.len && memcmp(in->data, p->last_in.data, in->len) == 0) {
        memcpy(key, p->last_key, 65);
        return;
    }
    unsigned char d[crypto_hash_sha256_BYTES];
    crypto_hash_sha256(d, (const unsigned char *)in->data, in->len);
    static const char hex[] = "0123456789abcdef";
    for (size_t i = 0; i < sizeof d; i++) {
        key[2 * i] = hex[d[i] >> 4];
        key[2 * i + 1] = hex[d[i] & 15];
    }
    key[64] = 0;
    marie_buf_reset(&p->last_in);
    if (!in->failed && marie_buf_put(&p->last_in, in->data, in->len) == 0)
        memcpy(p->last_key, key, 65);
}

/* A program's cache entry when it is not a marie component (no marker: never run), so that
 * the check from the cache alone knows it without reading the program. */
#define NOT_A_COMPONENT "not a marie component\n"

static char *cache_file(const marie_progcheck_t *p, const char *key)
{
    char *f = NULL;
    if (p->cache_dir && asprintf(&f, "%s/%s.json", p->cache_dir, key) < 0)
        f = NULL;
    return f;
}

static char *read_all(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = malloc(DESCRIBE_MAX + 1);
    *len = buf ? fread(buf, 1, DESCRIBE_MAX, f) : 0;
    fclose(f);
    if (buf)
        buf[*len] = 0;
    return buf;
}

static void write_cache(const marie_progcheck_t *p, const char *key, const char *text, size_t len)
{
    char *f = cache_file(p, key), *tmp = NULL;
    if (f && asprintf(&tmp, "%s.%d.tmp", f, (int)getpid()) >= 0) {
        FILE *o = fopen(tmp, "wb");
        if (o && fwrite(text, 1, len, o) == len && fclose(o) == 0)
            rename(tmp, f);
        else if (o)
            fclose(o);
        unlink(tmp);
    }
    free(tmp);
    free(f);
}

/* A description, or NULL when the text is not one. */
static marie_doc_t *parse_spec(const char *path, const char *text, size_t len)
{
    marie_errors_t ignore = {0};
    marie_doc_t *d = marie_doc_parse(path, text, len, &ignore);
    marie_errors_clear(&ignore);
    if (d && !marie_spec_valid(marie_doc_root(d))) {
        MARIE_CLEAR(d, marie_doc_destroy);
    }
    return d;
}

/* The description of c's program (*spec NULL: not a marie component). -1 with why on failure;
 * failures are not cached, so the next check tries again. */
static int describe(marie_progcheck_t *p, const char *path, const marie_component_cfg_t *c,
                    const marie_node_t **spec, char *why, size_t whylen)
{
    struct stat st;
    char key[65];
    if (stat(path, &st) < 0) {
        snprintf(why, whylen, "%s", strerror(errno));
        return -1;
    }
    cache_key(p, path, &st, c, key);
    spec_entry_t *e;
    for (e = p->entries; e; e = e->next)
        if (strcmp(e->key, key) == 0)
            break;
    if (!e) {
        size_t len = 0;
        char *f = cache_file(p, key), *text = f ? read_all(f, &len) : NULL;
        bool plain = text && len == strlen(NOT_A_COMPONENT) && memcmp(text, NOT_A_COMPONENT, len) == 0;
        marie_doc_t *doc = text && !plain ? parse_spec(path, text, len) : NULL;
        if (text && !doc && !plain)
            unlink(f);          /* a damaged cache file is described again */
        free(f);
        MARIE_CLEAR(text, free);
        if (!doc && !plain && p->cached_only) {
            /* the check that may run programs looks at it: the scan for the marker too (a
             * first `up` made it twice, in the manager and in its check's child) */
            p->must_run = true;
            snprintf(why, whylen, "not described yet");
            return -1;
        }
        if (!doc && !plain && !has_marker(path))
            write_cache(p, key, NOT_A_COMPONENT, strlen(NOT_A_COMPONENT));
        else if (!doc && !plain) {
            if (run_describe(path, c, kind_args(c), &text, &len, why, whylen) < 0)
                return -1;
            p->described++;
            if (!(doc = parse_spec(path, text, len))) {
                snprintf(why, whylen, "its output is not a component description");
                free(text);
                return -1;
            }
            write_cache(p, key, text, len);
            free(text);
        }
        if (!(e = calloc(1, sizeof *e))) {
            marie_doc_destroy(doc);
            snprintf(why, whylen, "out of memory");
            return -1;
        }
        memcpy(e->key, key, sizeof key);
        e->doc = doc;
        e->next = p->entries;
        p->entries = e;
    }
    *spec = e->doc ? marie_doc_root(e->doc) : NULL;
    return 0;
}

/* c's program exists and its entry fits the program's description, kept in *spec (NULL when the
 * program is not a marie component or could not be described). */
static int check_one(marie_progcheck_t *p, const marie_component_cfg_t *c, const marie_node_t **spec_out,
                     marie_errors_t *errs)
{
    const marie_node_t *en = marie_node_get(c->node, "exec");
    const char *file = c->file;
    int line = en ? en->line : c->line, col = en ? en->col : c->col;
    char *path = marie_am_resolve_exec(p->self_dir, c->file, c->exec);
    struct stat st;
    if (!path) {
        marie_errors_add(errs, file, line, col, "component '%s': program '%s' not found (looked in %s and PATH)",
                         c->name, c->exec, p->self_dir ? p->self_dir : "the manager's directory");
        return -1;
    }
    int rc = 0;
    if (stat(path, &st) < 0) {
        marie_errors_add(errs, file, line, col, "component '%s': program '%s': %s%s", c->name, path, strerror(errno),
                         c->exec[0] != '/' ? " (a relative exec starts from the system file's folder)" : "");
        rc = -1;
    } else if (!S_ISREG(st.st_mode) || access(path, X_OK) < 0) {
        marie_errors_add(errs, file, line, col, "component '%s': program '%s' is not an executable file", c->name,
                         path);
        rc = -1;
    } else {
        const marie_node_t *spec = NULL;
        char why[256] = "cannot describe it";
        if (describe(p, path, c, &spec, why, sizeof why) < 0) {
            char prog[256] = "";
            for (size_t i = 0; i < kind_args(c); i++)
                snprintf(prog + strlen(prog), sizeof prog - strlen(prog), " %s", c->args[i]);
            marie_errors_add(errs, file, line, col, "component '%s': '%s%s --describe' failed: %s", c->name, c->exec,
                             prog, why);
            rc = -1;
        } else if (spec) {
            rc = marie_spec_check(spec, c, errs);
            *spec_out = spec;
        }
    }
    free(path);
    return rc;
}

int marie_progcheck_system(marie_progcheck_t *p, const marie_system_t *sys, const char *only_host,
                           const char *fallback_host, marie_errors_t *errs)
{
    size_t n = sys->ncomponents ? sys->ncomponents : 1;
    const marie_node_t **specs = calloc(n, sizeof *specs);
    const marie_component_cfg_t **comps = calloc(n, sizeof *comps);
    int rc = 0;
    if (!specs || !comps) {
        free(specs);
        free(comps);
        marie_errors_add(errs, sys->file, 0, 0, "out of memory");
        return -1;
    }
    for (size_t i = 0; i < sys->ncomponents; i++) {
        const marie_component_cfg_t *c = comps[i] = &sys->components[i];
        if (c->shell || !c->exec)
            continue;     /* a shell command is the shell's business */
        if (only_host && strcmp(marie_am_component_host(sys, c, fallback_host), only_host) != 0)
            continue;
        rc |= check_one(p, c, &specs[i], errs);
    }
    /* Each channel carries one type: what one component publishes, the others read. */
    if (marie_spec_check_channels(specs, comps, sys->ncomponents, errs) < 0)
        rc = -1;
    free(specs);
    free(comps);
    return rc;
}

char *marie_progcheck_default_cache(void)
{
    const char *x = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    char *dir = NULL, *base = NULL;
    if (x && *x)
        base = strdup(x);
    else if (home && *home && asprintf(&base, "%s/.cache", home) < 0)
        base = NULL;
    if (!base)
        return NULL;
    mkdir(base, 0755);
    if (asprintf(&dir, "%s/marie", base) < 0)
        dir = NULL;
    if (dir)
        mkdir(dir, 0755);
    free(base);
    char *out = NULL;
    if (dir && asprintf(&out, "%s/describe", dir) < 0)
        out = NULL;
    free(dir);
    return out;
}
