/* lcm_send: sends messages through marie_bus_publish() for a peer of another make to check
 * (tests/core/test_lcm_python_peer.py: upstream LCM for Python reads them).
 *
 *   lcm_send URL CHANNEL SIZE...
 *
 * Message i (from 0) holds SIZE bytes, byte k being (k * 31 + i) mod 256. Prints "sends=1" when
 * marie's own socket sent them (0: liblcm did); exit 0 when every one was sent. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/bus/bus.h"

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: lcm_send URL CHANNEL SIZE...\n");
        return 2;
    }
    lcm_t *lcm = marie_bus_create(argv[1]);
    if (!lcm)
        return 1;
    printf("sends=%d\n", marie_bus_sends(lcm));
    int rc = 0;
    for (int i = 3; i < argc; i++) {
        size_t n = strtoul(argv[i], NULL, 10);
        uint8_t *p = malloc(n ? n : 1);
        for (size_t k = 0; k < n; k++)
            p[k] = (uint8_t)(k * 31 + (size_t)(i - 3));
        if (!p || marie_bus_publish(lcm, argv[2], p, (unsigned)n) != 0)
            rc = 1;
        free(p);
    }
    marie_bus_destroy(lcm);
    return rc;
}
