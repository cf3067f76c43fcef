/* ca_test: helpers for the CA tests over a real bus: start marie-ca, watch heartbeats, wait. */
#ifndef MARIE_TESTS_CA_TEST_H
#define MARIE_TESTS_CA_TEST_H

#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include <lcm/lcm.h>

#include "lcmtypes/marie_heartbeat_t.h"

/* Start build/bin/marie-ca (under $B) with these arguments (NULL-terminated, after the
 * program name). Returns the pid. */
pid_t cat_spawn(const char *const *args);
/* Send sig and reap; returns the wait status. */
int cat_stop(pid_t pid, int sig);
/* true while pid has not exited (reaps it when it has). */
bool cat_alive(pid_t pid);

/* The newest heartbeat seen from each component, kept by handling the bus. */
typedef struct cat_bus cat_bus_t;
cat_bus_t *cat_bus_create(void);
void cat_bus_destroy(cat_bus_t *b);
lcm_t *cat_lcm(cat_bus_t *b);
/* Handle the bus for up to ms milliseconds (or until done(user) is true, when given).
 * Returns true when done() became true. */
bool cat_spin(cat_bus_t *b, int ms, bool (*done)(void *user), void *user);
/* Wait for a heartbeat of `name` with state RUNNING newer than any seen before the call
 * started; false on timeout. */
bool cat_wait_running(cat_bus_t *b, const char *name, int ms);
/* Wait until a heartbeat of `name` shows counter (or "bad_input"/"drops") >= value; the
 * value last seen goes to *seen. */
bool cat_wait_counter(cat_bus_t *b, const char *name, const char *counter, int64_t value,
                      int ms, int64_t *seen);
/* Wait for a heartbeat of `name` in `state` (marie_state_t); its reason goes to reason. */
bool cat_wait_state(cat_bus_t *b, const char *name, int state, int ms, char *reason, size_t cap);
/* Number of heartbeats received from `name` so far. */
int64_t cat_heartbeats(cat_bus_t *b, const char *name);

/* A fresh state directory under /tmp (removed by cat_rmdir). */
void cat_tmpdir(char *out, size_t cap);
void cat_rmdir(const char *dir);

#endif
