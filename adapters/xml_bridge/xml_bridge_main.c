/* marie-xml-bridge: lets programs that cannot link LCM join the bus with XML documents over TCP. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/xml_bridge/xb_server.h"
#include "adapters/xml_bridge/xml_bridge_params.h"
#include "core/clear.h"
#include "core/component.h"

static const xb_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    xb_server_t *server;
    xb_server_stats_t last;
} bridge_t;

static const marie_param_spec_t params[] = XB_PARAMS;

static const marie_port_spec_t ports[] = {
    { NULL, NULL, 0, 0, NULL },
};

static void hook_bad_input(void *user, const char *counter, const char *reason)
{
    marie_component_bad_input(user, counter, "%s", reason);
}

static void hook_drop(void *user, int64_t n)
{
    marie_component_drop(user, n);
}

/* Mirrors the server's totals into the heartbeat counters. */
static void on_tick(marie_component_t *c, int64_t overruns)
{
    bridge_t *b = marie_component_user(c);
    if (!b->server)
        return;
    xb_server_stats_t st;
    xb_server_stats(b->server, &st);
    marie_component_count(c, "clients", (int64_t)st.clients - (int64_t)b->last.clients);
    marie_component_count(c, "published", (int64_t)(st.published - b->last.published));
    marie_component_count(c, "delivered", (int64_t)(st.delivered - b->last.delivered));
    marie_component_count(c, "error_replies", (int64_t)(st.errors - b->last.errors));
    b->last = st;
}

static int on_init(marie_component_t *c)
{
    if (!marie_component_every(c, 1.0, on_tick)) {
        marie_component_fail_reason(c, "cannot add the statistics timer");
        return -1;
    }
    return 0;
}

static int on_start(marie_component_t *c)
{
    bridge_t *b = marie_component_user(c);
    const xb_server_cfg_t *cfg = &params_of(c)->server;
    char why[160];
    if (xb_server_cfg_check(cfg, why, sizeof why) < 0) {
        marie_component_fail_reason(c, "xml bridge parameters out of range: %s", why);
        return -1;
    }
    xb_server_hooks_t hooks = { hook_bad_input, hook_drop, NULL, c };
    b->server = xb_server_create(cfg, marie_component_lcm(c), marie_component_loop(c), &hooks);
    if (!b->server) {
        marie_component_fail_reason(c, "cannot listen on %s:%lld", cfg->bind, (long long)cfg->port);
        return -1;
    }
    memset(&b->last, 0, sizeof b->last);
    marie_info("xml bridge listening on %s:%d", cfg->bind, xb_server_port(b->server));
    return 0;
}

static void shut(marie_component_t *c)
{
    bridge_t *b = marie_component_user(c);
    on_tick(c, 0);
    MARIE_CLEAR(b->server, xb_server_destroy);
}

static int on_stop(marie_component_t *c)
{
    shut(c);
    return 0;
}

static void on_abort(marie_component_t *c)
{
    shut(c);
}

static const marie_component_def_t def = {
    .kind = "xml_bridge",
    .ports = ports,
    .params = params, .params_size = sizeof(xb_params_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_stop = on_stop,
    .on_abort = on_abort,
    .on_quit = on_abort,
};

int main(int argc, char **argv)
{
    bridge_t b = { 0 };
    return marie_main(&def, argc, argv, &b);
}
