/* am_proto: names and defaults shared by the managers and their clients. */
#include "managers/am_proto.h"

#include <errno.h>
#include <lcm/lcm.h>

#include "core/time.h"
#include "core/auth.h"
#include "core/bus/bus.h"
#include "lcmtypes/marie_types.h"

#include <pwd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *const op_names[] = {
    [MARIE_AM_ORDER_T_OP_UP] = "up", [MARIE_AM_ORDER_T_OP_DOWN] = "down",
    [MARIE_AM_ORDER_T_OP_START] = "start", [MARIE_AM_ORDER_T_OP_STOP] = "stop",
    [MARIE_AM_ORDER_T_OP_RESTART] = "restart", [MARIE_AM_ORDER_T_OP_PAUSE] = "pause",
    [MARIE_AM_ORDER_T_OP_RESUME] = "resume", [MARIE_AM_ORDER_T_OP_MOVE] = "move",
    [MARIE_AM_ORDER_T_OP_TAIL] = "tail", [MARIE_AM_ORDER_T_OP_PING] = "ping",
};

const char *marie_am_op_name(int op)
{
    if (op > 0 && op < (int)(sizeof op_names / sizeof op_names[0]) && op_names[op])
        return op_names[op];
    return "?";
}

int marie_am_op_parse(const char *name)
{
    for (size_t i = 1; i < sizeof op_names / sizeof op_names[0]; i++)
        if (op_names[i] && strcmp(op_names[i], name) == 0)
            return (int)i;
    return -1;
}

const char *marie_am_key_path(const char *override)
{
    if (override && *override)
        return override;
    const char *e = getenv("MARIE_KEY");
    return e && *e ? e : "/etc/marie/key";
}

void marie_am_sender(char *buf, size_t len)
{
    char host[256] = "?";
    gethostname(host, sizeof host - 1);
    struct passwd *pw = getpwuid(geteuid());
    snprintf(buf, len, "%s@%s", pw ? pw->pw_name : "?", host);
}

const char *marie_am_component_host(const marie_system_t *sys, const marie_component_cfg_t *c, const char *fallback)
{
    if (c->host && *c->host)
        return c->host;
    if (sys->nhosts > 0)
        return sys->hosts[0];
    return fallback;
}

int marie_am_check_system(const marie_system_t *sys, marie_am_settings_t *st, marie_errors_t *errs)
{
    marie_am_settings_t def = {2.0, 200.0, 1 << 20, 3};
    *st = def;
    int rc = balance_read_cfg(sys, &st->balance, errs);
    const marie_node_t *m = marie_node_get(marie_doc_root(sys->doc), "manager");
    if (!m)
        return rc;
    static const char *const keys[] = {"status_hz", "log_rate", "log_max_bytes", "log_keep", NULL};
    if (m->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, m->file, m->line, m->col, "manager: expected a mapping");
        return -1;
    }
    if (marie_node_check_keys(m, keys, "manager", errs) < 0)
        return -1;
    const marie_node_t *v;
    int64_t iv = 0;
    if ((v = marie_node_get(m, "status_hz"))) {
        if (marie_node_double(v, &st->status_hz, errs) < 0)
            rc = -1;
        else if (st->status_hz < 0.5 || st->status_hz > 50) {
            marie_errors_add(errs, v->file, v->line, v->col, "status_hz: expected 0.5 to 50");
            rc = -1;
        }
    }
    if ((v = marie_node_get(m, "log_rate")) && marie_node_double(v, &st->log_rate, errs) < 0)
        rc = -1;
    if ((v = marie_node_get(m, "log_max_bytes"))) {
        if (marie_node_int(v, &iv, errs) < 0) {
            rc = -1;
        } else if (iv < 4096) {
            marie_errors_add(errs, v->file, v->line, v->col, "log_max_bytes: at least 4096");
            rc = -1;
        } else {
            st->log_max_bytes = iv;
        }
    }
    if ((v = marie_node_get(m, "log_keep"))) {
        if (marie_node_int(v, &iv, errs) < 0) {
            rc = -1;
        } else if (iv < 1 || iv > 100) {
            marie_errors_add(errs, v->file, v->line, v->col, "log_keep: expected 1 to 100");
            rc = -1;
        } else {
            st->log_keep = (int)iv;
        }
    }
    return rc;
}

int marie_am_send_order(lcm_t *lcm, const marie_auth_t *auth, marie_am_order_t *o, char *sender_buf,
                        size_t sender_len, const char *seq_file)
{
    marie_am_sender(sender_buf, sender_len);
    return marie_am_send_order_as(lcm, auth, o, sender_buf, seq_file);
}

int marie_am_send_order_as(lcm_t *lcm, const marie_auth_t *auth, marie_am_order_t *o, const char *sender,
                           const char *seq_file)
{
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    o->sender = (char *)sender;
    o->utime = marie_wall_us();
    o->seq = marie_auth_next_seq(seq_file);
    if (!o->host) o->host = "*";
    if (!o->arg) o->arg = "";
    if (!o->system_path) o->system_path = "";
    if (!o->system_text) o->system_text = "";
    int rc = marie_auth_sign_order(auth, o, mac);
    if (rc < 0)
        return rc;
    rc = marie_bus_publish_msg(lcm, MARIE_CH_AM_ORDER, &marie_type_am_order_t, o) < 0 ? -EIO : 0;
    o->mac_len = 0;          /* the MAC lived on this stack */
    return rc;
}
