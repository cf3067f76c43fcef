/* udpm_filter: the kernel filter of marie's LCM socket: short messages on channels nobody in the
 * process subscribes to are dropped before they wake it. */
#include "core/bus/udpm.h"

#include <errno.h>
#include <linux/filter.h>
#include <string.h>

#include "core/log.h"

/* The literal start every channel a subscription matches begins with (its length), and whether
 * the pattern is that literal whole. 0 and not whole: it may match any channel. */
size_t udpm_literal_prefix(const char *re, bool *whole)
{
    *whole = false;
    if (strchr(re, '|'))
        return 0;
    size_t n = strcspn(re, ".[]()*+?{}|^$\\");
    *whole = re[n] == '\0';
    if (!*whole && n > 0 && strchr("*?{", re[n]))
        n--;                    /* the character before may be absent */
    return n;
}

#define BPF_MAX 1024
#define UDP_HDR 8               /* a UDP socket's filter sees the UDP header first */

static size_t bpf_add(struct sock_filter *p, size_t n, uint16_t code, uint8_t jt, uint8_t jf, uint32_t k)
{
    if (n < BPF_MAX)
        p[n] = (struct sock_filter){code, jt, jf, k};
    return n + 1;
}

/* The kernel drops, before they wake anyone, short messages on channels no subscription can
 * match (at 500 components every process otherwise woke for every heartbeat): a classic BPF
 * filter on the socket, a block per subscription comparing the channel's literal start.
 * Fragments and what is not LCM's pass (to be put together, or counted). Rebuilt whenever the
 * subscriptions change; none when one of them may match anything. */
void udpm_refilter(udpm_t *u)
{
    struct sock_filter p[BPF_MAX];
    size_t n = 0;
    const uint32_t ACCEPT = 0xffffffffu;
    n = bpf_add(p, n, BPF_LD | BPF_W | BPF_LEN, 0, 0, 0);
    n = bpf_add(p, n, BPF_JMP | BPF_JGE | BPF_K, 1, 0, UDP_HDR + SHORT_HDR + 1);
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    n = bpf_add(p, n, BPF_LD | BPF_W | BPF_ABS, 0, 0, UDP_HDR);
    n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 1, 0, MAGIC_SHORT);
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    bool open = false;
    for (const udpm_sub_t *s = u->subs; s && !open; s = s->next) {
        if (s->removed)
            continue;
        bool whole;
        size_t len = udpm_literal_prefix(s->channel, &whole);
        if (len == 0) {
            open = true;
            break;
        }
        /* ld len; jge need; then per 4, 2 or 1 bytes: ld; jeq; then (whole) ld the NUL; jeq 0;
         * ret accept. A mismatch jumps to the next block: at most 3 + 2*(63/4+2) + 2 ahead. */
        size_t chunks = 0;
        for (size_t i = 0; i < len; i += len - i >= 4 ? 4 : len - i >= 2 ? 2 : 1)
            chunks++;
        size_t block = 2 + 2 * chunks + (whole ? 2 : 0) + 1, k = 0;
        const size_t at = UDP_HDR + SHORT_HDR;
#define NEXT ((uint8_t)(block - k - 1))
        n = bpf_add(p, n, BPF_LD | BPF_W | BPF_LEN, 0, 0, 0), k++;
        n = bpf_add(p, n, BPF_JMP | BPF_JGE | BPF_K, 0, NEXT, (uint32_t)(at + len + whole)), k++;
        for (size_t i = 0; i < len;) {
            size_t w = len - i >= 4 ? 4 : len - i >= 2 ? 2 : 1;
            uint32_t v = 0;
            for (size_t j = 0; j < w; j++)
                v = v << 8 | (uint8_t)s->channel[i + j];
            n = bpf_add(p, n, BPF_LD | (w == 4 ? BPF_W : w == 2 ? BPF_H : BPF_B) | BPF_ABS, 0, 0, (uint32_t)(at + i)), k++;
            n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 0, NEXT, v), k++;
            i += w;
        }
        if (whole) {
            n = bpf_add(p, n, BPF_LD | BPF_B | BPF_ABS, 0, 0, (uint32_t)(at + len)), k++;
            n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 0, NEXT, 0), k++;
        }
#undef NEXT
        n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    }
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, 0);
    struct sock_fprog prog = {(unsigned short)n, p};
    if (open || n > BPF_MAX) {
        int zero = 0;
        (void)setsockopt(u->fd, SOL_SOCKET, SO_DETACH_FILTER, &zero, sizeof zero);
        u->filtered = false;
    } else if (setsockopt(u->fd, SOL_SOCKET, SO_ATTACH_FILTER, &prog, sizeof prog) < 0) {
        marie_warn_ratelimited(60, "cannot filter the LCM bus in the kernel (%s): every message is read", strerror(errno));
        u->filtered = false;
    } else {
        u->filtered = true;
    }
}

