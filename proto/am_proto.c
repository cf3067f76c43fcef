/* am_proto: the managers' wire protocol as their clients see it (proto/am_proto.h). */
#include "proto/am_proto.h"

#include <errno.h>
#include <lcm/lcm.h>

#include "core/err.h"
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
    if (marie_auth_sign_order(auth, o, mac) < 0)
        return marie_fail(EINVAL);
    int rc = marie_bus_publish_msg(lcm, MARIE_CH_AM_ORDER, &marie_type_am_order_t, o);
    o->mac_len = 0;          /* the MAC lived on this stack */
    return rc < 0 ? marie_fail(EIO) : 0;
}
