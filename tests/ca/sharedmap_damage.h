/* sharedmap_damage: SharedMap logs built record by record, damaged (flips, zeroed ranges,
 * cut-outs), and the map that must survive: shared by test_ca_sharedmap_damage and the
 * fuzz target of the log. */
#ifndef MARIE_TESTS_CA_SHAREDMAP_DAMAGE_H
#define MARIE_TESTS_CA_SHAREDMAP_DAMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "ca/sharedmap.h"

#define SMD_MAXREC 160
#define SMD_MAXDATA 96

typedef struct {
    int op;                     /* SHAREDMAP_LOG_SET or _DEL */
    char key[16];
    uint8_t data[SMD_MAXDATA];
    size_t len;
    int64_t version, utime;
    size_t off, size;           /* in the undamaged image */
    long now;                   /* its start in the damaged image, -1 when cut away */
    int touched;                /* set by smd_mark_touched() */
} smd_rec_t;

typedef struct {
    smd_rec_t r[SMD_MAXREC];
    int n;
    uint8_t img[SMD_MAXREC * (SMD_MAXDATA + 80) + 8];
    size_t len;
} smd_log_t;

void smd_init(smd_log_t *l);                /* the magic only */
/* Appends a record (version and sequence number n + 1); len <= SMD_MAXDATA. */
void smd_add(smd_log_t *l, int op, const char *key, const uint8_t *data, size_t len);

/* Damage a copy of l->img of len bytes at `at` (clipped to the image). A cut moves every
 * later record back and returns the new length. */
void smd_zero(uint8_t *img, size_t len, size_t at, size_t n);
size_t smd_cut(smd_log_t *l, uint8_t *img, size_t len, size_t at, size_t n);

/* Marks the records whose bytes are not all where they were; returns how many. */
int smd_mark_touched(smd_log_t *l, const uint8_t *img, size_t len);

/* 0 when sm holds exactly the untouched records replayed in order (keys, values, versions,
 * times, map version); else -1 with the first difference in why. */
int smd_check_map(const sharedmap_t *sm, const smd_log_t *l, char *why, size_t cap);

#endif
