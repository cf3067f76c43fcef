/* udp: hand-made datagrams to the LCM group (tests/udp.h). */
#include "tests/udp.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

int test_udp_socket(void)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    unsigned char ttl = 0;
    if (fd >= 0)
        setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl);
    return fd;
}

ssize_t test_udp_send(int fd, const void *d, size_t n)
{
    struct sockaddr_in to = {.sin_family = AF_INET, .sin_port = htons(7667)};
    inet_pton(AF_INET, "239.255.76.67", &to.sin_addr);
    return sendto(fd, d, n, 0, (struct sockaddr *)&to, sizeof to);
}
