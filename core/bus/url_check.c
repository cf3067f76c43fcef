/* url_check: whether a bus URL is one liblcm opens, so that a system file's mistake is found
 * before its components start (core/config_check.c). */
#include "core/bus/bus.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One option of a udpm URL, "key=value" of length n: "" when liblcm takes it as meant, else why not. */
static const char *udpm_option(const char *p, size_t n)
{
    const char *eq = memchr(p, '=', n);
    if (!eq)
        return "an option is key=value";
    size_t kl = (size_t)(eq - p), vl = n - kl - 1;
    char v[32] = "", *end;
    if (vl == 0 || vl >= sizeof v)
        return "an option's value is empty or too long";
    memcpy(v, eq + 1, vl);
    long x = strtol(v, &end, 0);
    if (kl == 3 && strncmp(p, "ttl", 3) == 0)
        return *end || x < 0 || x > 255 ? "ttl is 0 to 255" : "";
    if (kl == 13 && strncmp(p, "recv_buf_size", 13) == 0)
        return *end || x < 1 || x > (1L << 30) ? "recv_buf_size is 1 to 1073741824 bytes" : "";
    if (kl == 13 && strncmp(p, "transmit_only", 13) == 0)
        return strcmp(v, "true") && strcmp(v, "false") && strcmp(v, "1") && strcmp(v, "0")
                   ? "transmit_only is true or false" : "";
    return "unknown option (udpm takes ttl, recv_buf_size and transmit_only)";
}

static int url_bad(char *why, size_t len, const char *reason)
{
    snprintf(why, len, "%s", reason);
    return -1;
}

int marie_bus_url_check(const char *url, char *why, size_t len)
{
    static const char *const providers[] = {"udpm", "mpudpm", "tcpq", "file", "memq", NULL};
    const char *sep = strstr(url, "://");
    size_t pl = sep ? (size_t)(sep - url) : 0;
    int known = -1;
    for (int i = 0; sep && providers[i]; i++)
        if (strlen(providers[i]) == pl && strncmp(url, providers[i], pl) == 0)
            known = i;
    if (!sep)
        return url_bad(why, len, "not PROVIDER://TARGET (udpm://239.255.76.67:7667?ttl=1)");
    if (known < 0)
        return url_bad(why, len, "no such LCM provider (udpm, mpudpm, tcpq, file or memq)");
    if (known > 1)
        return 0;
    const char *p = sep + 3;
    char addr[64];
    size_t n = strcspn(p, ":?");
    struct in_addr group;
    if (n == 0 || n >= sizeof addr)
        return url_bad(why, len, "no multicast group (udpm://239.255.76.67:7667)");
    memcpy(addr, p, n);
    addr[n] = 0;
    if (inet_pton(AF_INET, addr, &group) != 1 || !IN_MULTICAST(ntohl(group.s_addr)))
        return url_bad(why, len, "the group must be an IPv4 multicast address (224.0.0.0 to 239.255.255.255)");
    p += n;
    if (*p == ':') {
        char *end;
        unsigned long port = strtoul(p + 1, &end, 10);
        if (end == p + 1 || port == 0 || port > 65535 || (*end && *end != '?'))
            return url_bad(why, len, "the port is 1 to 65535");
        p = end;
    }
    if (*p && *p != '?')
        return url_bad(why, len, "unexpected text after the group");
    for (p += *p == '?'; *p; p += *p == '&') {
        size_t ol = strcspn(p, "&");
        const char *bad = udpm_option(p, ol);
        if (*bad)
            return url_bad(why, len, bad);
        p += ol;
    }
    return 0;
}
