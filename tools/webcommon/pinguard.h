/* pinguard: the web pages' PIN check, against guessing: the PIN compared in constant time, a
 * growing delay after each wrong one (per client address and for every client together), and a
 * lockout after too many, which doubles each time. Pure: the caller gives the clock. Shared by
 * the touch page and the viewer's controls (docs/face.md, "The PIN"). */
#ifndef TOOLS_PINGUARD_H
#define TOOLS_PINGUARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pinguard pinguard_t;

typedef struct {
    int max_failures;           /* wrong PINs in a row from one address before it is locked out */
    int max_failures_all;       /* wrong PINs in a row from all addresses before every one is */
    double delay_s;             /* after a wrong PIN its address waits this long, doubling with each */
    double delay_all_s;         /* ... and every address this long, doubling with each */
    double max_delay_s;         /* the longest such wait */
    double lockout_s;           /* the first lockout; each next one of the same scope lasts twice as
                                 * long, up to max_lockout_s */
    double max_lockout_s;
} pinguard_cfg_t;

/* 5 and 20 wrong PINs; waits of 1 s (0.1 s for everyone) doubling up to 30 s; lockouts of 60 s
 * doubling up to 1 h. */
void pinguard_cfg_defaults(pinguard_cfg_t *cfg);

typedef enum {
    PINGUARD_OK = 0,            /* the right PIN, in time */
    PINGUARD_WRONG,             /* compared: not the PIN */
    PINGUARD_WAIT,              /* too soon after a wrong PIN: not compared */
    PINGUARD_LOCKED,            /* locked out: not compared */
} pinguard_verdict_t;

typedef struct {
    pinguard_verdict_t verdict;
    double retry_s;             /* WRONG, WAIT, LOCKED: when this address may try again */
    bool locked_now;            /* this wrong PIN began a lockout (report it) */
    bool everyone;              /* the wait or lockout is every address's, not only this one's */
    int failures;               /* wrong PINs in a row from this address (WRONG) */
} pinguard_result_t;

/* NULL (errno EINVAL) when pin is shorter than 4 characters or longer than 64. The PIN is kept
 * as a keyed hash only. */
pinguard_t *pinguard_create(const char *pin, const pinguard_cfg_t *cfg);
void pinguard_destroy(pinguard_t *g);   /* NULL is a no-op */

/* One attempt from address addr (any text: "127.0.0.1") at now_us (a monotonic clock). */
pinguard_result_t pinguard_check(pinguard_t *g, const char *addr, const char *pin, int64_t now_us);

/* Counts since creation: attempts compared and refused, attempts refused uncompared, lockouts. */
typedef struct {
    int64_t wrong, refused_early, lockouts;
} pinguard_stats_t;
pinguard_stats_t pinguard_stats(const pinguard_t *g);

/* A random PIN of `digits` decimal digits (4 to 12) into out (digits + 1 bytes at least), from
 * the system's cryptographic generator. -1 (errno EINVAL) for a length out of range. */
int pinguard_random_pin(int digits, char *out, size_t len);

/* One line saying what a guesser can do against these settings with a PIN of `digits` digits,
 * for the docs and the start-up log. */
void pinguard_strength(const pinguard_cfg_t *cfg, int digits, char *out, size_t len);

#ifdef __cplusplus
}
#endif
#endif
