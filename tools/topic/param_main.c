/* param_main: marie-param, run as `marie param list|get|set COMPONENT [NAME [VALUE]]`: a running
 * component's parameters, and a change of one it declares dynamic (signed with the order key). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/auth.h"
#include "core/cli.h"
#include "core/component.h"
#include "core/bus/bus.h"
#include "core/spec.h"
#include "core/typeinfo.h"
#include "core/time.h"
#include "core/version.h"

#define EXIT_REFUSED 1
#define EXIT_USAGE 2
#define EXIT_TIMEOUT 3

typedef struct {
    int64_t request_id;
    marie_param_reply_t reply;
    int got;
    int64_t json;
} wait_t;

static void on_reply(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    wait_t *w = user;
    marie_param_reply_t r;
    if (w->got || marie_decode_checked(&marie_type_param_reply_t, rb->data, rb->data_size, &r) < 0)
        return;
    if (r.request_id != w->request_id) {
        marie_param_reply_t_decode_cleanup(&r);
        return;
    }
    w->reply = r;
    w->got = 1;
}

static int got(void *user) { return ((wait_t *)user)->got; }

static void print_reply(const wait_t *w, int op)
{
    const marie_param_reply_t *r = &w->reply;
    if (w->json) {
        printf("{\"component\":");
        marie_spec_json_str(stdout, r->component);
        printf(",\"ok\":%s,\"reason\":", r->ok ? "true" : "false");
        marie_spec_json_str(stdout, r->reason);
        printf(",\"params\":[");
        for (int i = 0; i < r->nparams; i++) {
            printf("%s{\"name\":", i ? "," : "");
            marie_spec_json_str(stdout, r->params[i].name);
            printf(",\"type\":\"%s\",\"value\":", r->params[i].type);
            marie_spec_json_str(stdout, r->params[i].value);
            printf(",\"dynamic\":%s,\"help\":", r->params[i].dynamic ? "true" : "false");
            marie_spec_json_str(stdout, r->params[i].help);
            printf("}");
        }
        printf("]}\n");
        return;
    }
    if (!r->ok) {
        fprintf(stderr, "marie param: %s: %s\n", r->component, r->reason);
        return;
    }
    for (int i = 0; i < r->nparams; i++) {
        if (op == MARIE_PARAM_REQUEST_T_OP_LIST)
            printf("%-20s %-7s %-8s %-20s %s\n", r->params[i].name, r->params[i].type,
                   r->params[i].dynamic ? "dynamic" : "-", r->params[i].value, r->params[i].help);
        else
            printf("%s\n", r->params[i].value);
    }
}

static int sign(marie_param_request_t *rq, const char *key, uint8_t mac[MARIE_AUTH_MAC_LEN])
{
    char why[512] = "";
    marie_auth_t *a = key ? marie_auth_load(key, why, sizeof why) : NULL;
    if (key && !a) {
        fprintf(stderr, "marie param: %s\n", why);
        return -1;
    }
    int rc = a ? marie_auth_sign_param(a, rq, mac) : 0;
    marie_auth_destroy(a);
    return rc;
}

int main(int argc, char **argv)
{
    const char *url = NULL, *key = getenv("MARIE_KEY");
    double timeout = 3;
    bool json = false, version = false;
    const marie_cli_opt_t opts[] = {
        {"url", MARIE_CLI_STRING, &url, 0, 0, "URL the bus (default $LCM_DEFAULT_URL, else marie's)"},
        {"key", MARIE_CLI_STRING, &key, 0, 0, "FILE the order key a set is signed with (default $MARIE_KEY)"},
        {"timeout", MARIE_CLI_DOUBLE, &timeout, 0.05, 3600, "S how long to wait for the answer (3)"},
        {"json", MARIE_CLI_FLAG, &json, 0, 0, "the answer as JSON"},
        {"version", MARIE_CLI_FLAG, &version, 0, 0, "print the version"},
        {0},
    };
    int rc = marie_cli_parse("marie param list|get|set COMPONENT [NAME [VALUE]]", opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (version) {
        printf("marie-param %s\n", MARIE_VERSION);
        return 0;
    }
    int n = argc - optind;
    char **a = argv + optind;
    int op = n >= 2 && strcmp(a[0], "list") == 0 && n == 2   ? MARIE_PARAM_REQUEST_T_OP_LIST
             : n == 3 && strcmp(a[0], "get") == 0             ? MARIE_PARAM_REQUEST_T_OP_GET
             : n == 4 && strcmp(a[0], "set") == 0             ? MARIE_PARAM_REQUEST_T_OP_SET
                                                              : 0;
    if (!op) {
        fprintf(stderr, "usage: marie param list COMPONENT | get COMPONENT NAME | set COMPONENT NAME VALUE\n");
        return EXIT_USAGE;
    }
    char sender[64];
    snprintf(sender, sizeof sender, "marie-param.%d", (int)getpid());
    wait_t w = {.request_id = marie_wall_us(), .json = json};
    int64_t now = marie_wall_us();
    marie_param_request_t rq = {.utime = now, .request_id = w.request_id, .sender = sender, .target = a[1],
                                .op = (int8_t)op, .name = n > 2 ? a[2] : "", .value = n > 3 ? a[3] : "",
                                .seq = marie_auth_next_seq(getenv("MARIE_SEQ_FILE")), .mac = (uint8_t[1]){0}};
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    lcm_t *lcm = marie_bus_create(url ? url : marie_default_url());
    marie_loop_t *loop = marie_loop_create();
    if (!lcm || !loop || marie_loop_add_bus(loop, lcm, 64) < 0 ||
        !marie_bus_subscribe(lcm, MARIE_CH_PARAM_REPLY, on_reply, &w)) {
        fprintf(stderr, "marie param: cannot open the bus\n");
        rc = 1;
    } else if (op == MARIE_PARAM_REQUEST_T_OP_SET && sign(&rq, key, mac) < 0) {
        rc = 1;
    } else if (marie_bus_publish_msg(lcm, MARIE_CH_PARAM, &marie_type_param_request_t, &rq) < 0) {
        fprintf(stderr, "marie param: cannot send\n");
        rc = 1;
    } else if (marie_loop_run_until(loop, (int)(timeout * 1000), got, &w) != 1) {
        fprintf(stderr, "marie param: no answer from '%s' within %g s (is it running?)\n", a[1], timeout);
        rc = EXIT_TIMEOUT;
    } else {
        print_reply(&w, op);
        rc = w.reply.ok ? 0 : EXIT_REFUSED;
        marie_param_reply_t_decode_cleanup(&w.reply);
    }
    marie_loop_destroy(loop);
    marie_bus_destroy(lcm);
    return rc;
}
