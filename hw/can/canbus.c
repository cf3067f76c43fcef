/* canbus: relay of CAN frames among AF_UNIX SOCK_SEQPACKET clients. */
#include "hw/can/canbus.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#define EMUBUS_MAX_CLIENTS 64

struct can_emubus {
    int lfd, epfd;
    char path[108];
    int clients[EMUBUS_MAX_CLIENTS];
    int nclients;
    can_emubus_stats_t stats;
};

can_emubus_t *can_emubus_create(const char *path)
{
    struct sockaddr_un sa;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    if (strlen(path) >= sizeof sa.sun_path) {
        errno = ENAMETOOLONG;
        return NULL;
    }
    strcpy(sa.sun_path, path);
    can_emubus_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    strcpy(b->path, path);
    b->lfd = socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (b->lfd < 0)
        goto err_free;
    unlink(path);
    if (bind(b->lfd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(b->lfd, 16) < 0)
        goto err_close;
    b->epfd = epoll_create1(EPOLL_CLOEXEC);
    if (b->epfd < 0)
        goto err_unlink;
    struct epoll_event ev = { .events = EPOLLIN, .data.fd = b->lfd };
    if (epoll_ctl(b->epfd, EPOLL_CTL_ADD, b->lfd, &ev) < 0)
        goto err_ep;
    return b;
err_ep:;
    int e = errno;
    close(b->epfd);
    errno = e;
err_unlink:
    e = errno;
    unlink(path);
    errno = e;
err_close:
    e = errno;
    close(b->lfd);
    errno = e;
err_free:
    e = errno;
    free(b);
    errno = e;
    return NULL;
}

void can_emubus_destroy(can_emubus_t *b)
{
    if (!b)
        return;
    for (int i = 0; i < b->nclients; i++)
        close(b->clients[i]);
    close(b->epfd);
    close(b->lfd);
    unlink(b->path);
    free(b);
}

int can_emubus_fd(const can_emubus_t *b) { return b->epfd; }
int can_emubus_nclients(const can_emubus_t *b) { return b->nclients; }
const can_emubus_stats_t *can_emubus_stats(const can_emubus_t *b) { return &b->stats; }

static void drop_client(can_emubus_t *b, int i)
{
    epoll_ctl(b->epfd, EPOLL_CTL_DEL, b->clients[i], NULL);
    close(b->clients[i]);
    b->clients[i] = b->clients[--b->nclients];
}

static void relay(can_emubus_t *b, int from, const void *pkt, size_t len)
{
    for (int i = 0; i < b->nclients; i++) {
        if (b->clients[i] == from)
            continue;
        if (send(b->clients[i], pkt, len, MSG_DONTWAIT | MSG_NOSIGNAL) == (ssize_t)len)
            b->stats.delivered++;
        else
            b->stats.overflow++;    /* a dead peer is noticed by its own EPOLLHUP */
    }
}

int can_emubus_inject(can_emubus_t *b, const struct can_frame *f)
{
    relay(b, -1, f, CAN_MTU);
    return 0;
}

static void accept_all(can_emubus_t *b)
{
    for (;;) {
        int fd = accept4(b->lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        struct epoll_event ev = { .events = EPOLLIN, .data.fd = fd };
        if (b->nclients >= EMUBUS_MAX_CLIENTS || epoll_ctl(b->epfd, EPOLL_CTL_ADD, fd, &ev) < 0) {
            close(fd);
            continue;
        }
        b->clients[b->nclients++] = fd;
        b->stats.clients++;
    }
}

/* Read everything waiting on one client; returns frames relayed, -1 if it hung up. */
static int drain(can_emubus_t *b, int fd)
{
    int n = 0;
    /* Bounded so one chatty client cannot starve the others. */
    for (int k = 0; k < 256; k++) {
        uint8_t pkt[CANFD_MTU + 8];
        ssize_t r = recv(fd, pkt, sizeof pkt, MSG_DONTWAIT);
        if (r < 0)
            return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? n : -1;
        if (r == 0)
            return -1;
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

int can_emubus_process(can_emubus_t *b)
{
    struct epoll_event evs[32];
    int total = 0;
    int n = epoll_wait(b->epfd, evs, 32, 0);
    if (n < 0)
        return errno == EINTR ? 0 : -errno;
    for (int i = 0; i < n; i++) {
        int fd = evs[i].data.fd;
        if (fd == b->lfd) {
            accept_all(b);
            continue;
        }
        int r = drain(b, fd);
        if (r < 0 || (evs[i].events & (EPOLLHUP | EPOLLERR) && r == 0)) {
            for (int j = 0; j < b->nclients; j++)
                if (b->clients[j] == fd) {
                    drop_client(b, j);
                    break;
                }
        } else {
            total += r;
        }
    }
    return total;
}
