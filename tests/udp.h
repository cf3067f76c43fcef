/* udp: hand-made datagrams to marie's default LCM group (239.255.76.67:7667, TTL 0, so they stay
 * on the host), for tests of what the bus reader does with datagrams LCM would never send. */
#ifndef MARIE_TEST_UDP_H
#define MARIE_TEST_UDP_H

#include <stddef.h>
#include <sys/types.h>

/* A socket to send from (each has its own source port), or -1. */
int test_udp_socket(void);
/* Sends n bytes from d as one datagram to the group; what sendto returns. */
ssize_t test_udp_send(int fd, const void *d, size_t n);

#endif
