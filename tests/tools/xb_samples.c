/* xb-samples: test helper that publishes sample messages of every marie type (printing their
 * fields in canonical form) or listens to the bus and prints what it hears. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <lcm/lcm.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "tests/xml_bridge/xb_canon.h"

static uint64_t fnv1a(const void *data, size_t len)
{
    const uint8_t *p = data;
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < len; i++)
        h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

typedef struct {
    const marie_typeinfo_t *t;
    marie_buf_t *out;
    int rc;
} enc_t;

static void on_doc(void *user, xb_node_t *root)
{
    enc_t *e = user;
    xb_error_t err;
    e->rc = xb_encode(e->t, root, e->out, &err);
    if (e->rc)
        fprintf(stderr, "xb-samples: %s: %s\n", e->t->name, err.reason);
}

static int publish(lcm_t *lcm, const char *prefix, int count, FILE *hashes)
{
    for (size_t i = 0; marie_typeinfos[i]; i++) {
        const marie_typeinfo_t *t = marie_typeinfos[i];
        for (int k = 0; k < count; k++) {
            marie_buf_t xml, bytes;
            xb_canon_t canon;
            marie_buf_init(&xml, 0);
            marie_buf_init(&bytes, 0);
            xb_canon_init(&canon);
            marie_buf_puts(&xml, "<m>");
            xb_sample(t, (uint32_t)(k * 1000 + (int)i + 1), &xml, &canon);
            marie_buf_puts(&xml, "</m>");
            enc_t e = { t, &bytes, -1 };
            xb_doc_parser_t *p = xb_doc_parser_create(NULL, on_doc, &e);
            if (!p || xb_doc_parser_feed(p, xml.data, xml.len) < 0 || e.rc != 0)
                return 1;
            xb_doc_parser_destroy(p);
            char ch[96];
            snprintf(ch, sizeof ch, "%s%s", prefix, t->short_name);
            if (lcm_publish(lcm, ch, bytes.data, (unsigned)bytes.len) < 0)
                return 1;
            printf("#%s\n%s", ch, xb_canon_text(&canon));
            if (hashes)
                fprintf(hashes, "%s %zu %016llx\n", ch, bytes.len,
                        (unsigned long long)fnv1a(bytes.data, bytes.len));
            marie_buf_free(&xml);
            marie_buf_free(&bytes);
            xb_canon_free(&canon);
            /* paced: lcm-logger, like any LCM subscriber, queues at most 30 messages between
             * its receive thread and its handler; a burst larger than that is lost when the
             * machine is loaded. XB_SAMPLES_PACE_MS sets the gap (default 2 ms). */
            const char *pace = getenv("XB_SAMPLES_PACE_MS");
            long ms = pace ? atol(pace) : 2;
            struct timespec ts = { ms / 1000, (ms % 1000) * 1000000 };
            nanosleep(&ts, NULL);
        }
    }
    return 0;
}

static int heard;

static void on_msg(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    printf("%s %u %016llx\n", channel, rb->data_size, (unsigned long long)fnv1a(rb->data, rb->data_size));
    fflush(stdout);
    heard++;
}

int main(int argc, char **argv)
{
    lcm_t *lcm = lcm_create(NULL);
    if (!lcm) {
        fprintf(stderr, "xb-samples: cannot open LCM\n");
        return 1;
    }
    int rc = 2;
    if (argc >= 3 && strcmp(argv[1], "publish") == 0) {
        FILE *h = argc >= 5 ? fopen(argv[4], "w") : NULL;
        rc = publish(lcm, argv[2], argc >= 4 ? atoi(argv[3]) : 2, h);
        if (h)
            fclose(h);
    } else if (argc >= 4 && strcmp(argv[1], "listen") == 0) {
        /* LCM queues at most 30 messages per subscription between its receive thread and
         * lcm_handle, and drops the rest: a 20x playback of the whole log is one burst, and
         * under load this thread is not scheduled in time, so the kernel delivers every
         * datagram (no RcvbufErrors) and LCM drops them. Keep them all. */
        lcm_subscription_set_queue_capacity(lcm_subscribe(lcm, argv[2], on_msg, NULL), 100000);
        double secs = atof(argv[3]);
        int want = argc >= 5 ? atoi(argv[4]) : -1;
        struct timespec t0, now;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        printf("listening\n");
        fflush(stdout);
        for (;;) {
            clock_gettime(CLOCK_MONOTONIC, &now);
            double el = (double)(now.tv_sec - t0.tv_sec) + (double)(now.tv_nsec - t0.tv_nsec) / 1e9;
            if (el >= secs || (want >= 0 && heard >= want))
                break;
            lcm_handle_timeout(lcm, 50);
        }
        rc = 0;
    } else {
        fprintf(stderr, "usage: xb-samples publish PREFIX [COUNT [HASHFILE]] | listen REGEX SECONDS [COUNT]\n");
    }
    lcm_destroy(lcm);
    return rc;
}
