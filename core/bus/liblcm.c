/* liblcm: the provider of every bus marie does not read itself (file://, memq://,
 * transmit_only, MARIE_LCM_RECEIVE=liblcm, and a bus made by plain lcm_create()): liblcm reads
 * and sends it, its receive thread handing messages over through its pipe. Its state is the
 * lcm_t itself. */
#include "core/bus/provider.h"

#include <dlfcn.h>
#include <errno.h>
#include <link.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/log.h"

/* ---- liblcm, opened at first use ----
 * A component whose buses marie reads and sends itself never calls liblcm; linked, liblcm and
 * what it needs (glib, pcre2) were mapped and relocated at every start (a quarter of the
 * dynamic loader's work). A program that calls liblcm itself links it, and dlopen() then finds
 * the copy in place. */
#define LCM_SONAME "liblcm.so.1"

static marie_liblcm_t lcm_fns;
static const marie_liblcm_t *lcm_ok;
static pthread_once_t lcm_once = PTHREAD_ONCE_INIT;

static void lcm_load(void)
{
    void *lib = dlopen(LCM_SONAME, RTLD_LAZY | RTLD_LOCAL);
    bool ok = lib != NULL;
#define LCM_LOAD(f) ok = ok && (*(void **)&lcm_fns.f = dlsym(lib, "lcm_" #f)) != NULL;
    MARIE_LIBLCM_FUNCS(LCM_LOAD)
#undef LCM_LOAD
    if (ok) {
        lcm_ok = &lcm_fns;      /* never closed: its receive threads and sockets outlive any use */
        return;
    }
    const char *why = dlerror();
    marie_error("cannot load LCM's library: %s", why ? why : LCM_SONAME);
    if (lib)
        dlclose(lib);
}

const marie_liblcm_t *marie_liblcm(void)
{
    pthread_once(&lcm_once, lcm_load);
    return lcm_ok ? lcm_ok : marie_fail_null(ENOENT);
}

static int is_liblcm(struct dl_phdr_info *info, size_t size, void *user)
{
    const char *slash = strrchr(info->dlpi_name, '/');
    return strncmp(slash ? slash + 1 : info->dlpi_name, "liblcm.so", 9) == 0;     /* .so.1, or its file */
}

/* The loader's list of what is mapped, read in memory: dlopen(RTLD_NOLOAD) searched the
 * library's path and opened the file to compare it (nine system calls at every bus's
 * creation, so at every component's start). */
bool marie_liblcm_in_process(void)
{
    return lcm_ok || dl_iterate_phdr(is_liblcm, NULL) != 0;
}

static void *liblcm_open(lcm_t *lcm, const char *url) { return lcm; }
static void liblcm_close(void *st) {}

typedef struct {
    lcm_subscription_t *ls;
    marie_bus_recv_t rv;
} sub_t;

static void on_message(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    marie_bus_recv_t rv = ((const sub_t *)user)->rv;   /* the handler may unsubscribe */
    rv.handler(rb, channel, rv.user);
    if (rv.verdict)
        rv.verdict(true, rv.user);          /* liblcm's copy is the subscriber's own */
}

static void *liblcm_subscribe(void *st, const char *channel, const marie_bus_recv_t *rv)
{
    sub_t *s = malloc(sizeof *s);
    if (!s)
        return NULL;
    s->rv = *rv;
    if (!(s->ls = marie_liblcm()->subscribe(st, channel, on_message, s))) {
        free(s);
        return marie_fail_null(EIO);
    }
    marie_liblcm()->subscription_set_queue_capacity(s->ls, MARIE_BUS_QUEUE);
    return s;
}

static void liblcm_unsubscribe(void *st, void *sub)
{
    sub_t *s = sub;
    marie_liblcm()->unsubscribe(st, s->ls);
    free(s);
}

static int liblcm_publish(void *st, const char *channel, const void *data, size_t len)
{
    if (len > UINT32_MAX)
        return marie_fail(EMSGSIZE);
    return marie_liblcm()->publish(st, channel, data, (unsigned)len) == 0 ? 0 : marie_fail(EIO);
}

static int liblcm_fd(void *st) { return marie_liblcm()->get_fileno(st); }

/* Called when the pipe is readable: the first handle does not block. */
static int liblcm_handle(void *st, int max)
{
    const marie_liblcm_t *l = marie_liblcm();
    int n = l->handle(st) == 0;
    while (n < max && l->handle_timeout(st, 0) > 0)
        n++;
    return n;
}

const marie_bus_provider_t marie_bus_liblcm = {
    .name = "liblcm",
    .open = liblcm_open,
    .close = liblcm_close,
    .subscribe = liblcm_subscribe,
    .unsubscribe = liblcm_unsubscribe,
    .publish = liblcm_publish,
    .fd = liblcm_fd,
    .handle = liblcm_handle,
};
