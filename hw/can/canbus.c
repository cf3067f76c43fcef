/* canbus: relay of CAN frames among AF_UNIX SOCK_SEQPACKET clients. */
#include "hw/can/canbus.h"

#include <errno.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <linux/sockios.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "core/err.h"
#include "hw/can/can.h"

#define EMUBUS_MAX_CLIENTS 64
/* Frames held for a client whose socket is full. A connected AF_UNIX packet socket takes
 * what fits in the sender's buffer (net.core.wmem_default, about 280 frames of ~770 bytes'
 * accounting each); a SocketCAN socket's receive buffer holds a few hundred frames too, and
 * these 512 more keep a reader late by some ms from losing what a real controller keeps. */
#define EMUBUS_QUEUE 512

typedef struct {
    uint8_t len;
    uint8_t data[CANFD_MTU];
} pkt_t;

typedef struct {
    int fd;
    pkt_t *q;                   /* ring of EMUBUS_QUEUE, allocated when first needed */
    int head, count;
    bool want_out;              /* POLLOUT asked of the loop */
    bool filtered;              /* it told us its filters: send only what they take */
    uint32_t nfilters;
    can_err_mask_t err_mask;
    struct can_filter filters[CAN_EMU_MAX_FILTERS];
} client_t;

struct can_emubus {
    marie_loop_t *loop;
    int lfd;
    char path[108];
    client_t clients[EMUBUS_MAX_CLIENTS];
    int nclients;
    can_emubus_stats_t stats;
};

static void on_listen(marie_loop_t *loop, int fd, short revents, void *user);

can_emubus_t *can_emubus_create(marie_loop_t *loop, const char *path)
{
    /* Bound under a temporary name and renamed once listening: whoever sees PATH can connect. */
    struct sockaddr_un sa;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    int n = snprintf(sa.sun_path, sizeof sa.sun_path, "%s.new", path);
    if (n < 0 || (size_t)n >= sizeof sa.sun_path)
        return marie_fail_null(ENAMETOOLONG);
    can_emubus_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    strcpy(b->path, path);
    b->loop = loop;
    b->lfd = socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (b->lfd < 0)
        goto err_free;
    unlink(sa.sun_path);
    if (bind(b->lfd, (struct sockaddr *)&sa, sizeof sa) < 0)
        goto err_close;
    if (listen(b->lfd, 16) < 0 || rename(sa.sun_path, path) < 0) {
        MARIE_KEEP_ERRNO(unlink(sa.sun_path));
        goto err_close;
    }
    if (marie_loop_add_fd(loop, b->lfd, POLLIN, on_listen, b) < 0)
        goto err_unlink;
    return b;
err_unlink:
    MARIE_KEEP_ERRNO(unlink(path));
err_close:
    MARIE_KEEP_ERRNO(close(b->lfd));
err_free:
    MARIE_KEEP_ERRNO(free(b));
    return NULL;
}

void can_emubus_destroy(can_emubus_t *b)
{
    if (!b)
        return;
    for (int i = 0; i < b->nclients; i++) {
        marie_loop_remove_fd(b->loop, b->clients[i].fd);
        close(b->clients[i].fd);
        free(b->clients[i].q);
    }
    marie_loop_remove_fd(b->loop, b->lfd);
    close(b->lfd);
    unlink(b->path);
    free(b);
}

int can_emubus_nclients(const can_emubus_t *b) { return b->nclients; }
const can_emubus_stats_t *can_emubus_stats(const can_emubus_t *b) { return &b->stats; }

static void drop_client(can_emubus_t *b, int i)
{
    marie_loop_remove_fd(b->loop, b->clients[i].fd);
    close(b->clients[i].fd);
    free(b->clients[i].q);
    b->clients[i] = b->clients[--b->nclients];
}

static void want_out(can_emubus_t *b, client_t *c, bool on)
{
    if (c->want_out == on)
        return;
    if (marie_loop_set_events(b->loop, c->fd, POLLIN | (on ? POLLOUT : 0)) == 0)
        c->want_out = on;
}

/* Hand the held frames over, oldest first, as far as the client's socket takes them. */
static void flush(can_emubus_t *b, client_t *c)
{
    while (c->count > 0) {
        pkt_t *p = &c->q[c->head];
        ssize_t r = send(c->fd, p->data, p->len, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            break;
        if (r == (ssize_t)p->len)
            b->stats.delivered++;
        else
            b->stats.overflow++;    /* a dead peer is noticed by its own POLLHUP */
        c->head = (c->head + 1) % EMUBUS_QUEUE;
        c->count--;
    }
    want_out(b, c, c->count > 0);
}

static void deliver(can_emubus_t *b, client_t *c, const void *pkt, size_t len)
{
    if (c->count == 0) {
        ssize_t r = send(c->fd, pkt, len, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (r == (ssize_t)len) {
            b->stats.delivered++;
            return;
        }
        if (r >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) {
            b->stats.overflow++;
            return;
        }
    }
    if (!c->q && !(c->q = malloc(EMUBUS_QUEUE * sizeof *c->q))) {
        b->stats.overflow++;
        return;
    }
    if (c->count == EMUBUS_QUEUE) {
        b->stats.overflow++;        /* its receive queue is full: a real controller drops too */
        return;
    }
    pkt_t *p = &c->q[(c->head + c->count) % EMUBUS_QUEUE];
    p->len = (uint8_t)len;
    memcpy(p->data, pkt, len);
    c->count++;
    want_out(b, c, true);
}

/* What the kernel's CAN_RAW filters would let through to this client. */
static bool takes(const client_t *c, const void *pkt)
{
    if (!c->filtered)
        return true;
    canid_t id;
    memcpy(&id, pkt, sizeof id);
    if (id & CAN_ERR_FLAG)
        return (id & c->err_mask & CAN_ERR_MASK) != 0;
    return can_filter_match(c->filters, c->nfilters, id);
}

static void relay(can_emubus_t *b, int from, const void *pkt, size_t len)
{
    for (int i = 0; i < b->nclients; i++) {
        client_t *c = &b->clients[i];
        if (c->fd == from)
            continue;
        if (takes(c, pkt))
            deliver(b, c, pkt, len);
        else
            b->stats.filtered++;
    }
}

/* A client's filter packet (can.h): true when pkt is one, taken or counted bad. */
static bool filter_packet(can_emubus_t *b, client_t *c, const uint8_t *pkt, size_t len)
{
    if (len < CAN_EMU_FILTER_HDR || memcmp(pkt, CAN_EMU_FILTER_MAGIC, 4) != 0)
        return false;
    uint32_t n, mask;
    memcpy(&n, pkt + 4, 4);
    memcpy(&mask, pkt + 8, 4);
    if (n > CAN_EMU_MAX_FILTERS || len != CAN_EMU_FILTER_HDR + 8 * (size_t)n) {
        b->stats.bad++;
        return true;
    }
    for (uint32_t i = 0; i < n; i++) {
        memcpy(&c->filters[i].can_id, pkt + CAN_EMU_FILTER_HDR + 8 * i, 4);
        memcpy(&c->filters[i].can_mask, pkt + CAN_EMU_FILTER_HDR + 8 * i + 4, 4);
    }
    c->nfilters = n;
    c->err_mask = mask;
    c->filtered = true;
    return true;
}

int can_emubus_unread(const can_emubus_t *b)
{
    int n = 0;
    for (int i = 0; i < b->nclients; i++) {
        int q = 0;
        /* SIOCOUTQ on our end: what we sent that the client has not read yet. */
        if (b->clients[i].count > 0 || (ioctl(b->clients[i].fd, SIOCOUTQ, &q) == 0 && q > 0))
            n++;
    }
    return n;
}

int can_emubus_inject(can_emubus_t *b, const struct can_frame *f)
{
    relay(b, -1, f, CAN_MTU);
    return 0;
}

static void on_client(marie_loop_t *loop, int fd, short revents, void *user);

static void accept_all(can_emubus_t *b)
{
    for (;;) {
        int fd = accept4(b->lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        if (b->nclients >= EMUBUS_MAX_CLIENTS || marie_loop_add_fd(b->loop, fd, POLLIN, on_client, b) < 0) {
            close(fd);
            continue;
        }
        b->clients[b->nclients++] = (client_t){ .fd = fd };
        b->stats.clients++;
    }
}

/* Read everything waiting on one client; returns frames relayed, -1 if it hung up. */
static int drain(can_emubus_t *b, client_t *c)
{
    int n = 0, fd = c->fd;
    /* Bounded so one chatty client cannot starve the others. */
    for (int k = 0; k < 256; k++) {
        uint8_t pkt[CAN_EMU_FILTER_HDR + 8 * CAN_EMU_MAX_FILTERS + 8];
        ssize_t r = recv(fd, pkt, sizeof pkt, MSG_DONTWAIT);
        if (r < 0)
            return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? n : -1;
        if (r == 0)
            return -1;
        if (r != CAN_MTU && r != CANFD_MTU && filter_packet(b, c, pkt, (size_t)r))
            continue;
        if ((r != CAN_MTU && r != CANFD_MTU) || pkt[4] > (r == CAN_MTU ? CAN_MAX_DLEN : CANFD_MAX_DLEN)) {
            b->stats.bad++;
            continue;
        }
        b->stats.frames++;
        relay(b, fd, pkt, (size_t)r);
        n++;
    }
    return n;
}

static void on_listen(marie_loop_t *loop, int fd, short revents, void *user)
{
    accept_all(user);
}

static int find(const can_emubus_t *b, int fd)
{
    for (int i = 0; i < b->nclients; i++)
        if (b->clients[i].fd == fd)
            return i;
    return -1;
}

static void on_client(marie_loop_t *loop, int fd, short revents, void *user)
{
    can_emubus_t *b = user;
    int i = find(b, fd);
    if (i < 0)
        return;
    if (revents & POLLOUT)
        flush(b, &b->clients[i]);
    int r = (revents & (POLLIN | POLLHUP | POLLERR)) ? drain(b, &b->clients[i]) : 0;
    /* drain relays to the others, which may drop none: i still names this client */
    if (r < 0 || (revents & (POLLHUP | POLLERR) && r == 0))
        drop_client(b, i);
}

int can_emubus_process(can_emubus_t *b)
{
    int total = 0;
    accept_all(b);
    for (int i = 0; i < b->nclients;) {
        if (b->clients[i].count > 0)
            flush(b, &b->clients[i]);
        int r = drain(b, &b->clients[i]);
        if (r < 0) {
            drop_client(b, i);      /* the last one moved here: look at slot i again */
            continue;
        }
        total += r;
        i++;
    }
    return total;
}
