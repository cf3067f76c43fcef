/* webpin: the PIN gate of the web pages' requests (the touch page's, the viewer's controls): the
 * component's PIN parameters read once, each request's PIN checked by pinguard, and what a
 * refusal says to the page, to the counters and, for a lockout, to the bus (docs/face.md). */
#ifndef TOOLS_WEBPIN_H
#define TOOLS_WEBPIN_H

#include <stdbool.h>
#include <stddef.h>

#include "core/component.h"
#include "tools/webcommon/pinguard.h"
#include "tools/webcommon/webserve.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The PIN parameters every page component declares alike. */
typedef struct {
    const char *pin;            /* empty: a random one of `digits` digits */
    int64_t digits;
    int64_t max_failures, max_failures_all;
    double lockout_s;
} webpin_params_t;

/* The guard for c's pages, its PIN into pin_out (printed by the caller). NULL with the reason as
 * c's failure when a parameter is out of range (a PIN shorter than 4 characters). */
pinguard_t *webpin_open(marie_component_t *c, const webpin_params_t *p, char *pin_out, size_t len);

/* Whether the request of page `client` (from addr) with `pin` may go on. Refused: the page is
 * told why and when to try again, counted (wrong_pin, pin_refused), and a lockout is a
 * `pin_lockout` warning event. */
bool webpin_allow(pinguard_t *g, marie_component_t *c, webserve_t *w, int client, const char *addr,
                  const char *pin);

#ifdef __cplusplus
}
#endif
#endif
