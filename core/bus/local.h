/* local: the same-host fast path's parts (core/bus/local*.c): a channel's registry, where its
 * publishers name their rings and its subscribers their doorbells, and the doorbell itself.
 * Only core/bus uses it. See docs/transport.md, "The same-host fast path". */
#ifndef MARIE_BUS_LOCAL_H
#define MARIE_BUS_LOCAL_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>

#include "core/shm.h"

#define LOCAL_PUBS 16               /* publishers of one channel on a host */
#define LOCAL_SUBS 64               /* subscribing buses of one channel on a host */
#define LOCAL_BELL_MAX 64           /* a doorbell's name */

/* One publisher: its ring (a marie_shm segment). ticket orders registrations. */
typedef struct {
    _Atomic int32_t pid;            /* 0: free */
    _Atomic uint32_t ticket;
    char segment[MARIE_SHM_NAME_MAX];
} local_pub_t;

/* One subscribing bus: its doorbell (a FIFO), rung by publishers only while it sleeps. */
typedef struct {
    _Atomic int32_t pid;            /* 0: free */
    _Atomic uint32_t ticket;
    _Atomic uint32_t sleeping;
    _Atomic int32_t cpu;            /* the CPU it went to sleep on (a publisher's hint), or -1 */
    char bell[LOCAL_BELL_MAX];
} local_sub_t;

/* A channel's registry, /dev/shm/marie-local.<netns>.<channel>: shared by the user's processes
 * (mode 0600) in one network namespace, as LCM's multicast is. Entries change under a lock;
 * publishing and reading only load and store atomics. */
typedef struct {
    uint32_t magic, version;
    _Atomic uint32_t tickets;       /* the last ticket given: every change takes one */
    _Atomic uint32_t subs_used;     /* subs[] past this were never used */
    local_pub_t pubs[LOCAL_PUBS];
    local_sub_t subs[LOCAL_SUBS];
} local_registry_t;

typedef struct {
    local_registry_t *reg;
    int fd;                         /* open while in use: its locks say so (local_reg.c) */
    char path[320];
} local_reg_t;

/* The channel's registry's path, in this network namespace on this host. */
void local_reg_path(char *out, size_t cap, const char *channel);
/* Opens (or makes) the channel's registry. 0, or -1 with errno. */
int local_reg_open(local_reg_t *r, const char *channel);
/* Lets go of it, and removes it when nobody is registered any more. */
void local_reg_close(local_reg_t *r);
/* Registers this process's publisher (its ring) or subscriber (its doorbell): the entry's index,
 * or -1 with errno (ENOSPC: the table is full, counting dead processes' entries as free). */
int local_reg_add_pub(local_reg_t *r, const char *segment);
int local_reg_add_sub(local_reg_t *r, const char *bell);
void local_reg_remove_pub(local_reg_t *r, int i);
void local_reg_remove_sub(local_reg_t *r, int i);

/* A doorbell: a FIFO this process reads (polled by the loop) and keeps open for writing itself,
 * so it never reads end-of-file. */
typedef struct {
    int fd, self;                   /* read end; this process's own write end */
    char name[LOCAL_BELL_MAX];
} local_bell_t;
int local_bell_open(local_bell_t *b);
void local_bell_close(local_bell_t *b);
void local_bell_drain(const local_bell_t *b);
/* Rings the doorbell named `name` through *fd (opened on first use, -1 before; closed and set
 * to -1 when its reader is gone). 0, or -1 when nobody reads it any more. */
int local_bell_ring(const char *name, int *fd);

#endif
