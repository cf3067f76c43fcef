/* liblcm: the provider of every bus marie does not read itself (file://, memq://,
 * transmit_only, MARIE_LCM_RECEIVE=liblcm, and a bus made by plain lcm_create()): liblcm reads
 * and sends it, its receive thread handing messages over through its pipe. Its state is the
 * lcm_t itself. */
#include "core/bus/provider.h"

#include <errno.h>
#include <stdlib.h>

#include "core/err.h"

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
    if (!(s->ls = lcm_subscribe(st, channel, on_message, s))) {
        free(s);
        return marie_fail_null(EIO);
    }
    lcm_subscription_set_queue_capacity(s->ls, MARIE_BUS_QUEUE);
    return s;
}

static void liblcm_unsubscribe(void *st, void *sub)
{
    sub_t *s = sub;
    lcm_unsubscribe(st, s->ls);
    free(s);
}

static int liblcm_publish(void *st, const char *channel, const void *data, size_t len)
{
    if (len > UINT32_MAX)
        return marie_fail(EMSGSIZE);
    return lcm_publish(st, channel, data, (unsigned)len) == 0 ? 0 : marie_fail(EIO);
}

static int liblcm_fd(void *st) { return lcm_get_fileno(st); }

/* Called when the pipe is readable: the first handle does not block. */
static int liblcm_handle(void *st, int max)
{
    int n = lcm_handle(st) == 0;
    while (n < max && lcm_handle_timeout(st, 0) > 0)
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
