/* can_link: CAN bus I/O for loop-based drivers. */
#include "hw/can/can_link.h"

#include <errno.h>
#include <stdarg.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/clear.h"
#include "core/err.h"
#include "core/log.h"
#include "core/time.h"

#define MAX_FILTERS 16
#define BUSOFF_HOLD_US 500000   /* let the bus settle before asking for a restart */

struct can_link {
    marie_loop_t *loop;
    char url[128];
    can_bus_t *bus;
    struct can_filter filters[MAX_FILTERS];
    size_t nfilters;
    can_link_frame_cb_t on_frame;
    can_link_event_cb_t on_event;
    void *user;
    marie_timer_t *timer;
    can_stats_t past;           /* stats of closed connections */
    int64_t busoff_since;
    bool was_busoff;
    uint64_t tx_fail_logged;
};

static void event(can_link_t *l, const char *kind, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void event(can_link_t *l, const char *kind, const char *fmt, ...)
{
    char text[200];
    MARIE_VFORMAT(text, fmt);
    if (l->on_event)
        l->on_event(l->user, kind, text);
}

static void accumulate(can_stats_t *a, const can_stats_t *b)
{
    a->rx += b->rx; a->tx += b->tx; a->rx_filtered += b->rx_filtered; a->rx_bad += b->rx_bad;
    a->err_frames += b->err_frames; a->bus_off += b->bus_off; a->tx_errors += b->tx_errors;
}

static void disconnect(can_link_t *l, const char *why)
{
    if (!l->bus)
        return;
    marie_loop_remove_fd(l->loop, can_bus_fd(l->bus));
    accumulate(&l->past, can_bus_stats(l->bus));
    MARIE_CLEAR(l->bus, can_bus_close);
    event(l, "disconnected", "%s: %s", l->url, why);
}

/* POLLOUT only while the emulated bus holds frames its server had no room for. */
static void sync_events(can_link_t *l)
{
    if (l->bus)
        marie_loop_set_events(l->loop, can_bus_fd(l->bus), can_bus_events(l->bus));
}

static void on_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    can_link_t *l = user;
    struct can_frame f;
    if (revents & POLLOUT) {
        int r = can_bus_flush(l->bus);
        if (r < 0) {
            disconnect(l, strerror(errno));
            return;
        }
        sync_events(l);
    }
    /* Bounded: the loop gets back control even under a frame storm. */
    for (int i = 0; i < 512 && l->bus; i++) {
        int r = can_bus_read(l->bus, &f);
        if (r == 0)
            break;
        if (r < 0) {
            disconnect(l, strerror(errno));
            return;
        }
        if (f.can_id & CAN_ERR_FLAG) {
            can_bus_health_t h = can_bus_health(l->bus);
            if (h == CAN_BUS_BUS_OFF && !l->was_busoff) {
                l->was_busoff = true;
                l->busoff_since = marie_mono_us();
                event(l, "bus_off", "%s: controller is bus-off", l->url);
            } else if (h != CAN_BUS_BUS_OFF && l->was_busoff) {
                l->was_busoff = false;
                event(l, "bus_active", "%s: bus recovered (%s)", l->url, can_health_name(h));
            }
            continue;
        }
        if (l->was_busoff) {
            l->was_busoff = false;
            event(l, "bus_active", "%s: frames flow again", l->url);
        }
        l->on_frame(l->user, &f);
    }
    if (l->bus && (revents & (POLLHUP | POLLERR)) && !can_bus_is_socketcan(l->bus))
        disconnect(l, "hang-up");
}

static int connect_bus(can_link_t *l)
{
    can_bus_t *b = can_bus_open(l->url);
    if (!b)
        return -1;
    int r = can_bus_set_filters(b, l->filters, l->nfilters);
    if (r == 0)
        r = can_bus_set_err_mask(b, CAN_ERR_BUSOFF | CAN_ERR_RESTARTED | CAN_ERR_CRTL | CAN_ERR_TX_TIMEOUT);
    if (r == 0)
        r = marie_loop_add_fd(l->loop, can_bus_fd(b), POLLIN, on_readable, l);
    if (r < 0) {
        MARIE_KEEP_ERRNO(can_bus_close(b));
        return -1;
    }
    l->bus = b;
    return 0;
}

static void on_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    can_link_t *l = user;
    if (!l->bus) {
        if (connect_bus(l) == 0)
            event(l, "connected", "%s: reconnected", l->url);
        return;
    }
    if (l->was_busoff && marie_mono_us() - l->busoff_since >= BUSOFF_HOLD_US) {
        int r = can_bus_restart(l->bus);
        event(l, "bus_restart", "%s: restart requested: %s", l->url, r == 0 ? "ok" : strerror(errno));
        l->busoff_since = marie_mono_us();
        if (r == 0 && can_bus_health(l->bus) != CAN_BUS_BUS_OFF)
            l->was_busoff = false;
    }
}

can_link_t *can_link_open(marie_loop_t *loop, const char *url, const struct can_filter *filters, size_t n,
                          can_link_frame_cb_t on_frame, can_link_event_cb_t on_event, void *user)
{
    if (n > MAX_FILTERS || !url || strlen(url) >= sizeof ((can_link_t *)0)->url)
        return marie_fail_null(EINVAL);
    can_link_t *l = calloc(1, sizeof *l);
    if (!l)
        return NULL;
    l->loop = loop;
    strcpy(l->url, url);
    if (n)
        memcpy(l->filters, filters, n * sizeof *filters);
    l->nfilters = n;
    l->on_frame = on_frame;
    l->on_event = on_event;
    l->user = user;
    if (connect_bus(l) < 0)
        goto err;
    l->timer = marie_loop_add_wall_timer(loop, 250000, on_timer, l);
    if (!l->timer)
        goto err_bus;
    return l;
err_bus:
    MARIE_KEEP_ERRNO(marie_loop_remove_fd(loop, can_bus_fd(l->bus)); can_bus_close(l->bus));
err:
    MARIE_KEEP_ERRNO(free(l));
    return NULL;
}

void can_link_close(can_link_t *l)
{
    if (!l)
        return;
    if (l->bus) {
        marie_loop_remove_fd(l->loop, can_bus_fd(l->bus));
        can_bus_close(l->bus);
    }
    marie_loop_remove_timer(l->loop, l->timer);
    free(l);
}

int can_link_send(can_link_t *l, const struct can_frame *f, int n)
{
    int sent = 0;
    for (int i = 0; i < n; i++) {
        if (!l->bus) {
            l->past.tx_errors++;
            continue;
        }
        if (can_bus_write(l->bus, &f[i]) == 0) {
            sent++;
            continue;
        }
        int err = errno;
        if (err == EPIPE || err == ECONNRESET || err == ENOTCONN) {
            disconnect(l, strerror(err));
            continue;
        }
        /* ENOBUFS / EAGAIN (queue full) or ENETDOWN (bus-off, link down): tell once per burst. */
        if (can_bus_stats(l->bus)->tx_errors + l->past.tx_errors >= l->tx_fail_logged * 2 + 1) {
            l->tx_fail_logged = can_bus_stats(l->bus)->tx_errors + l->past.tx_errors;
            event(l, "tx_error", "%s: send failed: %s (%llu so far)", l->url, strerror(err),
                  (unsigned long long)l->tx_fail_logged);
        }
    }
    sync_events(l);
    return sent;
}

bool can_link_up(const can_link_t *l) { return l->bus && !l->was_busoff; }

can_stats_t can_link_stats(const can_link_t *l)
{
    can_stats_t s = l->past;
    if (l->bus)
        accumulate(&s, can_bus_stats(l->bus));
    return s;
}

can_bus_t *can_link_bus(can_link_t *l) { return l->bus; }
