/* marie-test-order: sends hand-made manager orders (signed, unsigned, forged with another
 * key, the same signed order again, or with chosen times) and prints each answer, for the
 * refusal tests. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/component.h"
#include "core/config.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "proto/am_proto.h"
#include "core/auth.h"

static int64_t want_seq;
static char answer[1100];
static int nreplies, nevents;

static void on_reply(const lcm_recv_buf_t *rbuf, const char *ch, const marie_am_reply_t *r, void *user)
{
    if (r->seq == want_seq && strcmp(r->sender, (const char *)user) == 0) {
        nreplies++;
        snprintf(answer, sizeof answer, "%s hosts=%d", r->ok ? "ok" : r->reason, r->nhosts);
    }
}

static void on_event(const lcm_recv_buf_t *rbuf, const char *ch, const marie_event_t *e, void *user)
{
    nevents += strcmp(e->kind, "order_refused") == 0;
}

int main(int argc, char **argv)
{
    const char *key = NULL, *mode = "signed", *sender = "tester@test";
    int64_t seq = 0, utime = 0;
    double age = 0;
    int repeat = 1, flood = 0, have_utime = 0, opt;
    while ((opt = getopt(argc, argv, "k:m:s:S:r:u:A:F:")) != -1) {
        switch (opt) {
        case 'k': key = optarg; break;
        case 'm': mode = optarg; break;
        case 's': seq = atoll(optarg); break;
        case 'S': sender = optarg; break;
        case 'r': repeat = atoi(optarg); break;
        case 'u': utime = atoll(optarg); have_utime = 1; break;     /* absolute, us */
        case 'A': age = atof(optarg); break;                         /* s before now; < 0: ahead */
        case 'F': flood = atoi(optarg); break;                       /* send N, count answers */
        default: return 2;
        }
    }
    if (optind + 1 > argc) {
        fprintf(stderr, "usage: marie-test-order [-k KEY] [-m signed|unsigned|forged] [-s SEQ] [-u UTIME] [-A AGE_S] [-S SENDER] [-r N] [-F N] OP [TARGET...]\n");
        return 2;
    }
    if (strcmp(mode, "garbage") == 0) {
        /* malformed messages on every channel a manager reads, including a string length
         * of -1, which liblcm's own decoder would follow into a crash */
        lcm_t *lcm = lcm_create(marie_default_url());
        if (!lcm)
            return 1;
        static const char *const channels[] = {MARIE_CH_AM_ORDER, "MARIE_HEARTBEAT", MARIE_CH_AM_STATUS,
                                               MARIE_CH_AM_STATUS_REQUEST};
        srand(7);
        for (int i = 0; i < repeat; i++) {
            uint8_t buf[300];
            size_t n = (size_t)(rand() % (int)sizeof buf);
            for (size_t k = 0; k < n; k++)
                buf[k] = (uint8_t)rand();
            if (i % 2 == 0 && n > 24) {
                static uint8_t none[1];
                marie_am_order_t o = {.sender = "x", .host = "*", .arg = "", .system_path = "", .system_text = "",
                                      .mac = none};
                int len = marie_am_order_t_encode(buf, 0, sizeof buf, &o);
                if (len > 20) {
                    n = (size_t)len;
                    memset(buf + 16, 0xff, 4);
                }
            }
            lcm_publish(lcm, channels[i % 4], buf, (unsigned)n);
        }
        lcm_destroy(lcm);
        printf("sent %d\n", repeat);
        return 0;
    }
    int op = marie_am_op_parse(argv[optind]);
    if (op < 0)
        return 2;
    marie_auth_t *auth = NULL;
    if (strcmp(mode, "forged") == 0) {
        uint8_t k[MARIE_AUTH_KEY_LEN];
        memset(k, 0x5a, sizeof k);
        auth = marie_auth_from_key(k);
    } else if (strcmp(mode, "signed") == 0) {
        char err[256];
        auth = marie_auth_load(key, err, sizeof err);
        if (!auth) {
            fprintf(stderr, "%s\n", err);
            return 2;
        }
    }
    lcm_t *lcm = lcm_create(marie_default_url());
    if (!lcm)
        return 1;
    marie_am_reply_t_subscription_t *sub = marie_am_reply_t_subscribe(lcm, MARIE_CH_AM_REPLY, on_reply, (void *)sender);
    marie_event_t_subscription_t *esub = marie_event_t_subscribe(lcm, MARIE_CH_EVENT, on_event, NULL);
    int64_t when = marie_wall_us() - (int64_t)(age * 1e6);
    marie_am_order_t o = {
        .utime = have_utime ? utime : when, .sender = (char *)sender, .seq = seq ? seq : when, .host = "*",
        .op = (int8_t)op, .ntargets = argc - optind - 1, .targets = argv + optind + 1, .arg = "",
        .system_path = "", .system_text = "",
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN] = {0};
    o.mac = mac;             /* liblcm memcpy()s even an empty array: never NULL */
    if (auth)
        marie_auth_sign_order(auth, &o, mac);
    want_seq = o.seq;
    if (flood > 0) {
        /* one every 3 ms (faster, the kernel drops them before anyone can count), then
         * what came back within 1.5 s */
        int64_t t0 = marie_mono_us();
        for (int i = 0; i < flood; i++) {
            marie_am_order_t_publish(lcm, MARIE_CH_AM_ORDER, &o);
            lcm_handle_timeout(lcm, 3);
        }
        int64_t end = marie_mono_us() + 1500000;
        while (marie_mono_us() < end)
            lcm_handle_timeout(lcm, 100);
        printf("sent %d replies %d events %d seconds %.1f\n", flood, nreplies, nevents,
               (double)(marie_mono_us() - t0) / 1e6);
        repeat = 0;
    }
    for (int i = 0; i < repeat; i++) {
        answer[0] = 0;
        marie_am_order_t_publish(lcm, MARIE_CH_AM_ORDER, &o);
        int64_t end = marie_mono_us() + 2000000;
        while (!answer[0] && marie_mono_us() < end)
            lcm_handle_timeout(lcm, 100);
        printf("%s\n", answer[0] ? answer : "no answer");
        fflush(stdout);
    }
    marie_am_reply_t_unsubscribe(lcm, sub);
    marie_event_t_unsubscribe(lcm, esub);
    marie_auth_destroy(auth);
    lcm_destroy(lcm);
    return 0;
}
