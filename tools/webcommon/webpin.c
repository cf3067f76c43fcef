/* webpin: the PIN gate of the web pages' requests. */
#include "tools/webcommon/webpin.h"

#include <stdio.h>

#include "core/log.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"

pinguard_t *webpin_open(marie_component_t *c, const webpin_params_t *p, char *pin_out, size_t len)
{
    pinguard_cfg_t cfg;
    pinguard_cfg_defaults(&cfg);
    cfg.max_failures = (int)p->max_failures;
    cfg.max_failures_all = (int)p->max_failures_all;
    cfg.lockout_s = p->lockout_s;
    if (p->digits < 4 || p->digits > 12 || p->max_failures < 1 || p->max_failures_all < p->max_failures ||
        !(p->lockout_s >= 1 && p->lockout_s <= cfg.max_lockout_s)) {
        marie_component_fail_reason(c, "pin_digits is 4 to 12, pin_max_failures at least 1 and at most "
                                       "pin_max_failures_all, pin_lockout_s 1 to %.0f", cfg.max_lockout_s);
        return NULL;
    }
    if (p->pin[0])
        snprintf(pin_out, len, "%s", p->pin);
    else if (pinguard_random_pin((int)p->digits, pin_out, len) < 0) {
        marie_component_fail_reason(c, "cannot draw a random PIN");
        return NULL;
    }
    pinguard_t *g = pinguard_create(pin_out, &cfg);
    if (!g) {
        marie_component_fail_reason(c, "pin: 4 to 64 characters (a longer one is harder to guess)");
        return NULL;
    }
    char line[256];
    pinguard_strength(&cfg, (int)p->digits, line, sizeof line);
    marie_info("PIN guard: %d wrong in a row lock an address out, %d lock everyone out, for %.0f s doubling "
               "up to %.0f s; with random PINs, %s", cfg.max_failures, cfg.max_failures_all, cfg.lockout_s,
               cfg.max_lockout_s, line);
    return g;
}

bool webpin_allow(pinguard_t *g, marie_component_t *c, webserve_t *w, int client, const char *addr,
                  const char *pin)
{
    pinguard_result_t r = pinguard_check(g, addr, pin ? pin : "", marie_mono_us());
    char text[200];
    switch (r.verdict) {
    case PINGUARD_OK:
        return true;
    case PINGUARD_WRONG:
        marie_component_count(c, "wrong_pin", 1);
        snprintf(text, sizeof text, "wrong PIN%s: try again in %.0f s", r.locked_now ? ", too many: locked" : "",
                 r.retry_s < 1 ? 1 : r.retry_s);
        break;
    case PINGUARD_WAIT:
    case PINGUARD_LOCKED:
        marie_component_count(c, "pin_refused", 1);
        snprintf(text, sizeof text, "%s: try again in %.0f s",
                 r.verdict == PINGUARD_LOCKED ? "locked after too many wrong PINs" : "too soon after a wrong PIN",
                 r.retry_s < 1 ? 1 : r.retry_s);
        break;
    }
    webserve_notice(w, client, "error", text);
    if (r.locked_now && r.everyone)
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "pin_lockout", "too many wrong PINs in a row from all "
                              "addresses (the last from %s): every address locked out for %.0f s", addr, r.retry_s);
    else if (r.locked_now)
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "pin_lockout", "%d wrong PINs in a row from %s: locked "
                              "out for %.0f s", r.failures, addr, r.retry_s);
    return false;
}
