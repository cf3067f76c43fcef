/* can: SocketCAN raw sockets and emulated-bus clients behind the same frame API. */
#include "hw/can/can.h"

#include <errno.h>
#include <fcntl.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <linux/can/netlink.h>
#include <linux/can/raw.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>

#include "core/err.h"

/* Frames held for the emulated bus's server, whose socket takes what fits in our send buffer
 * until it runs again; a real controller's queue drains on the wire by itself. A server that
 * does not run (a loaded machine, a simulator descheduled) does not advance simulated time
 * either, so holding the frame, not losing it, is what a bus would do. */
#define EMU_TX_QUEUE 64

typedef struct {
    uint8_t len;
    uint8_t data[CANFD_MTU];
} tx_pkt_t;

struct can_bus {
    int fd;
    bool socketcan;
    bool server;                /* an "emu:" bus: a server to tell our filters to */
    int ifindex;
    char url[128];
    struct can_filter filters[CAN_EMU_MAX_FILTERS];  /* emulated backend filters in software */
    size_t nfilters;
    can_err_mask_t err_mask;
    bool fd_on;
    can_bus_health_t state;
    can_stats_t stats;
    tx_pkt_t *txq;              /* ring of EMU_TX_QUEUE, allocated when first needed */
    int tx_head, tx_count;
};

/* ---- pure helpers ---- */

bool can_filter_match(const struct can_filter *filters, size_t n, canid_t id)
{
    if (n == 0)
        return true;
    for (size_t i = 0; i < n; i++) {
        canid_t mask = filters[i].can_mask & ~CAN_INV_FILTER;
        bool hit = (id & mask) == (filters[i].can_id & mask & ~CAN_INV_FILTER);
        if (filters[i].can_id & CAN_INV_FILTER)
            hit = !hit;
        if (hit)
            return true;
    }
    return false;
}

int can_err_decode(const struct can_frame *f, can_err_info_t *info)
{
    if (!(f->can_id & CAN_ERR_FLAG))
        return marie_fail(EINVAL);
    memset(info, 0, sizeof *info);
    uint32_t c = f->can_id & CAN_ERR_MASK;
    uint8_t d1 = f->len > 1 ? f->data[1] : 0;
    info->classes = c;
    info->bus_off = c & CAN_ERR_BUSOFF;
    info->restarted = c & CAN_ERR_RESTARTED;
    info->tx_timeout = c & CAN_ERR_TX_TIMEOUT;
    info->ack = c & CAN_ERR_ACK;
    info->bus_error = c & (CAN_ERR_BUSERROR | CAN_ERR_PROT);
    if (c & CAN_ERR_CRTL) {
        info->passive = d1 & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE);
        info->warning = d1 & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING);
        info->overflow = d1 & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW);
    }
    if (c & CAN_ERR_CNT) {
        info->tx_errors = f->data[6];
        info->rx_errors = f->data[7];
    }
    return 0;
}

can_bus_health_t can_health_next(can_bus_health_t cur, const can_err_info_t *info)
{
    if (!info)
        return CAN_BUS_ACTIVE;            /* a data frame got through */
    if (info->bus_off)
        return CAN_BUS_BUS_OFF;
    if (info->restarted)
        return CAN_BUS_ACTIVE;
    if (info->passive)
        return CAN_BUS_PASSIVE;
    if (info->warning)
        return cur == CAN_BUS_BUS_OFF ? cur : CAN_BUS_WARNING;
    return cur;
}

const char *can_health_name(can_bus_health_t s)
{
    switch (s) {
    case CAN_BUS_ACTIVE: return "active";
    case CAN_BUS_WARNING: return "warning";
    case CAN_BUS_PASSIVE: return "passive";
    case CAN_BUS_BUS_OFF: return "bus-off";
    }
    return "?";
}

char *can_frame_str(const struct can_frame *f, char *buf, size_t cap)
{
    size_t o = 0;
    if (f->can_id & CAN_EFF_FLAG)
        o += snprintf(buf, cap, "%08X#", f->can_id & CAN_EFF_MASK);
    else
        o += snprintf(buf, cap, "%03X#", f->can_id & CAN_SFF_MASK);
    if (f->can_id & CAN_RTR_FLAG) {
        snprintf(buf + o, cap > o ? cap - o : 0, "R");
        return buf;
    }
    for (int i = 0; i < f->len && i < 8 && o < cap; i++)
        o += snprintf(buf + o, cap - o, "%02X", f->data[i]);
    return buf;
}

/* ---- backends ---- */

static int set_nonblock(int fd)
{
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0)
        return -1;
    return 0;
}

static can_bus_t *bus_new(int fd, bool socketcan, const char *url)
{
    can_bus_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    b->fd = fd;
    b->socketcan = socketcan;
    snprintf(b->url, sizeof b->url, "%s", url);
    return b;
}

static int open_socketcan(const char *ifname, int *ifindex)
{
    int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0)
        return -1;
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0)
        goto err;
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0)
        goto err;
    can_err_mask_t none = 0;
    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &none, sizeof none);
    *ifindex = ifr.ifr_ifindex;
    return fd;
err:
    MARIE_KEEP_ERRNO(close(fd));
    return -1;
}

static int open_emu(const char *path)
{
    struct sockaddr_un sa;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    if (strlen(path) >= sizeof sa.sun_path)
        return marie_fail(ENAMETOOLONG);
    strcpy(sa.sun_path, path);
    int fd = socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    if (connect(fd, (struct sockaddr *)&sa, sizeof sa) < 0) {
        MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    return fd;
}

can_bus_t *can_bus_open(const char *url)
{
    int fd, ifindex = 0;
    bool sc;
    if (!url)
        return marie_fail_null(EINVAL);
    if (strncmp(url, "can:", 4) == 0) {
        fd = open_socketcan(url + 4, &ifindex);
        sc = true;
    } else if (strncmp(url, "emu:", 4) == 0) {
        fd = open_emu(url + 4);
        sc = false;
    } else {
        return marie_fail_null(EINVAL);
    }
    if (fd < 0)
        return NULL;
    can_bus_t *b = bus_new(fd, sc, url);
    if (!b) {
        close(fd);
        return marie_fail_null(ENOMEM);
    }
    b->ifindex = ifindex;
    b->server = !sc;
    return b;
}

can_bus_t *can_bus_from_fd(int fd)
{
    if (set_nonblock(fd) < 0)
        return NULL;
    can_bus_t *b = bus_new(fd, false, "fd:");
    if (!b)
        errno = ENOMEM;
    return b;
}

void can_bus_close(can_bus_t *bus)
{
    if (!bus)
        return;
    close(bus->fd);
    free(bus->txq);
    free(bus);
}

int can_bus_fd(const can_bus_t *bus) { return bus->fd; }
bool can_bus_is_socketcan(const can_bus_t *bus) { return bus->socketcan; }
const char *can_bus_url(const can_bus_t *bus) { return bus->url; }
can_bus_health_t can_bus_health(const can_bus_t *bus) { return bus->state; }
const can_stats_t *can_bus_stats(const can_bus_t *bus) { return &bus->stats; }

/* The emulated bus's server gets our filters and error mask (can.h, CAN_EMU_FILTER_MAGIC).
 * Not sent (a full socket) only means the server sends more than we read: not an error. */
static void tell_server(can_bus_t *bus)
{
    if (!bus->server)
        return;
    uint8_t pkt[CAN_EMU_FILTER_HDR + CAN_EMU_MAX_FILTERS * 8];
    uint32_t n = (uint32_t)bus->nfilters, mask = bus->err_mask;
    memcpy(pkt, CAN_EMU_FILTER_MAGIC, 4);
    memcpy(pkt + 4, &n, 4);
    memcpy(pkt + 8, &mask, 4);
    for (uint32_t i = 0; i < n; i++) {
        memcpy(pkt + CAN_EMU_FILTER_HDR + 8 * i, &bus->filters[i].can_id, 4);
        memcpy(pkt + CAN_EMU_FILTER_HDR + 8 * i + 4, &bus->filters[i].can_mask, 4);
    }
    (void)send(bus->fd, pkt, CAN_EMU_FILTER_HDR + 8 * n, MSG_DONTWAIT | MSG_NOSIGNAL);
}

int can_bus_set_filters(can_bus_t *bus, const struct can_filter *filters, size_t n)
{
    if (n > CAN_EMU_MAX_FILTERS)
        return marie_fail(EINVAL);
    if (bus->socketcan) {
        /* The kernel filters before our socket's queue, so unwanted frames cost nothing. */
        if (setsockopt(bus->fd, SOL_CAN_RAW, CAN_RAW_FILTER, n ? filters : NULL,
                       (socklen_t)(n * sizeof *filters)) < 0)
            return -1;
    }
    if (n)
        memcpy(bus->filters, filters, n * sizeof *filters);
    bus->nfilters = n;
    tell_server(bus);
    return 0;
}

int can_bus_set_err_mask(can_bus_t *bus, can_err_mask_t mask)
{
    if (bus->socketcan &&
        setsockopt(bus->fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) < 0)
        return -1;
    bus->err_mask = mask & CAN_ERR_MASK;
    tell_server(bus);
    return 0;
}

/* One frame of either kind, error frames noted, filters applied: 1, 0, or -1 with errno. */
static int read_any(can_bus_t *bus, struct canfd_frame *out, bool *is_fd)
{
    for (;;) {
        /* Room beyond CANFD_MTU so an oversized packet is seen as such, not truncated. */
        union { struct can_frame cf; struct canfd_frame fd; uint8_t raw[CANFD_MTU + 8]; } u;
        ssize_t n = recv(bus->fd, &u, sizeof u, 0);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return 0;
            return -1;
        }
        if (n == 0)
            return bus->socketcan ? 0 : marie_fail(EPIPE);    /* the bus daemon closed us */
        bool fd = n == (ssize_t)CANFD_MTU;
        if ((n != (ssize_t)CAN_MTU && !fd) || u.cf.len > (fd ? CANFD_MAX_DLEN : CAN_MAX_DLEN)) {
            bus->stats.rx_bad++;
            continue;
        }
        if (fd && !bus->fd_on) {
            bus->stats.rx_filtered++;
            continue;
        }
        if (!fd && (u.cf.can_id & CAN_ERR_FLAG)) {
            if (!bus->socketcan && !(u.cf.can_id & bus->err_mask))
                continue;
            can_err_info_t info;
            can_err_decode(&u.cf, &info);
            can_bus_health_t ns = can_health_next(bus->state, &info);
            if (ns == CAN_BUS_BUS_OFF && bus->state != CAN_BUS_BUS_OFF)
                bus->stats.bus_off++;
            bus->state = ns;
            bus->stats.err_frames++;
        } else {
            if (!bus->socketcan && !can_filter_match(bus->filters, bus->nfilters, u.cf.can_id)) {
                bus->stats.rx_filtered++;
                continue;
            }
            if (bus->state != CAN_BUS_ACTIVE)
                bus->state = can_health_next(bus->state, NULL);
        }
        memset(out, 0, sizeof *out);
        memcpy(out, &u, fd ? CANFD_MTU : CAN_MTU);
        *is_fd = fd;
        bus->stats.rx++;
        return 1;
    }
}

int can_bus_read(can_bus_t *bus, struct can_frame *f)
{
    for (;;) {
        struct canfd_frame any;
        bool fd;
        int r = read_any(bus, &any, &fd);
        if (r <= 0)
            return r;
        if (fd) {                   /* FD on, but this caller reads classic frames only */
            bus->stats.rx_filtered++;
            continue;
        }
        memcpy(f, &any, CAN_MTU);
        return 1;
    }
}

int can_bus_read_fd(can_bus_t *bus, struct canfd_frame *f, bool *is_fd)
{
    return read_any(bus, f, is_fd);
}

int can_bus_enable_fd(can_bus_t *bus, bool on)
{
    int v = on;
    if (bus->socketcan && setsockopt(bus->fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &v, sizeof v) < 0)
        return -1;
    bus->fd_on = on;
    return 0;
}

/* 1 sent, 0 when the socket is full, or -1 with errno. */
static int send_now(can_bus_t *bus, const void *p, size_t len)
{
    for (;;) {
        ssize_t n = send(bus->fd, p, len, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (n == (ssize_t)len) {
            bus->stats.tx++;
            return 1;
        }
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            return 0;
        return n < 0 ? -1 : marie_fail(EIO);
    }
}

int can_bus_flush(can_bus_t *bus)
{
    while (bus->tx_count > 0) {
        tx_pkt_t *p = &bus->txq[bus->tx_head];
        int r = send_now(bus, p->data, p->len);
        if (r == 0)
            break;
        if (r < 0)
            return r;
        bus->tx_head = (bus->tx_head + 1) % EMU_TX_QUEUE;
        bus->tx_count--;
    }
    return bus->tx_count;
}

short can_bus_events(const can_bus_t *bus) { return POLLIN | (bus->tx_count > 0 ? POLLOUT : 0); }

static int send_packet(can_bus_t *bus, const void *p, size_t len)
{
    int r = 0;
    /* Held frames go first: the bus keeps a sender's order. */
    if (bus->tx_count == 0 || (r = can_bus_flush(bus)) == 0) {
        r = send_now(bus, p, len);
        if (r == 1)
            return 0;
    }
    if (r < 0 || bus->socketcan) {
        bus->stats.tx_errors++;
        return r < 0 ? -1 : marie_fail(EAGAIN);     /* SocketCAN: the controller's queue is full */
    }
    if (!bus->txq && !(bus->txq = malloc(EMU_TX_QUEUE * sizeof *bus->txq))) {
        bus->stats.tx_errors++;
        return marie_fail(ENOMEM);
    }
    if (bus->tx_count == EMU_TX_QUEUE) {
        bus->stats.tx_errors++;
        return marie_fail(EAGAIN);
    }
    tx_pkt_t *q = &bus->txq[(bus->tx_head + bus->tx_count) % EMU_TX_QUEUE];
    q->len = (uint8_t)len;
    memcpy(q->data, p, len);
    bus->tx_count++;
    return 0;
}

int can_bus_write_fd(can_bus_t *bus, const struct canfd_frame *f)
{
    if (!bus->fd_on)
        return marie_fail(EPROTONOSUPPORT);
    if (f->len > CANFD_MAX_DLEN)
        return marie_fail(EINVAL);
    return send_packet(bus, f, CANFD_MTU);
}

int can_bus_write(can_bus_t *bus, const struct can_frame *f)
{
    if (f->len > CAN_MAX_DLEN)
        return marie_fail(EINVAL);
    return send_packet(bus, f, CAN_MTU);
}

/* RTM_NEWLINK { ifindex, IFLA_LINKINFO { KIND "can", DATA { IFLA_CAN_RESTART = 1 } } } */
static int netlink_restart(int ifindex)
{
    struct {
        struct nlmsghdr nh;
        struct ifinfomsg ifi;
        char attrs[128];
    } req;
    memset(&req, 0, sizeof req);
    req.nh.nlmsg_type = RTM_NEWLINK;
    req.nh.nlmsg_flags = NLM_F_REQUEST | NLM_F_ACK;
    req.nh.nlmsg_seq = 1;
    req.ifi.ifi_family = AF_UNSPEC;
    req.ifi.ifi_index = ifindex;
    size_t len = NLMSG_LENGTH(sizeof req.ifi);
    struct rtattr *linkinfo = (struct rtattr *)((char *)&req + NLMSG_ALIGN(len));
    linkinfo->rta_type = IFLA_LINKINFO;
    struct rtattr *kind = (struct rtattr *)RTA_DATA(linkinfo);
    kind->rta_type = IFLA_INFO_KIND;
    kind->rta_len = RTA_LENGTH(4);
    memcpy(RTA_DATA(kind), "can", 4);
    struct rtattr *data = (struct rtattr *)((char *)kind + RTA_ALIGN(kind->rta_len));
    data->rta_type = IFLA_INFO_DATA;
    struct rtattr *restart = (struct rtattr *)RTA_DATA(data);
    restart->rta_type = IFLA_CAN_RESTART;
    restart->rta_len = RTA_LENGTH(sizeof(uint32_t));
    uint32_t one = 1;
    memcpy(RTA_DATA(restart), &one, sizeof one);
    data->rta_len = RTA_LENGTH(RTA_ALIGN(restart->rta_len));
    linkinfo->rta_len = (unsigned short)(RTA_LENGTH(RTA_ALIGN(kind->rta_len)) + data->rta_len);
    req.nh.nlmsg_len = (uint32_t)(NLMSG_ALIGN(len) + RTA_ALIGN(linkinfo->rta_len));

    int fd = socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
    if (fd < 0)
        return -1;
    int ret = 0;
    if (send(fd, &req, req.nh.nlmsg_len, 0) < 0) {
        ret = -1;
    } else {
        char buf[512];
        ssize_t n = recv(fd, buf, sizeof buf, 0);
        struct nlmsghdr *nh = (struct nlmsghdr *)buf;
        int nlerr = n >= (ssize_t)NLMSG_LENGTH(sizeof(struct nlmsgerr)) && nh->nlmsg_type == NLMSG_ERROR
                        ? ((struct nlmsgerr *)NLMSG_DATA(nh))->error : 0;
        if (n < 0)
            ret = -1;
        else if (nlerr < 0)
            ret = marie_fail(-nlerr);       /* netlink answers with a negative errno */
    }
    MARIE_KEEP_ERRNO(close(fd));
    return ret;
}

int can_bus_restart(can_bus_t *bus)
{
    int r = 0;
    if (bus->socketcan)
        r = netlink_restart(bus->ifindex);
    if (r == 0)
        bus->state = CAN_BUS_ACTIVE;
    return r;
}
