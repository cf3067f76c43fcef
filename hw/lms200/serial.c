/* serial: termios for the LMS200 line. Only the fd is touched, so tests hand it a pty. */
#include "hw/lms200/serial.h"

#include <errno.h>
#include <fcntl.h>
#include <stdbool.h>
#include <unistd.h>

#include "core/err.h"

static const struct { int baud; speed_t speed; } rates[] = {
    { 9600, B9600 }, { 19200, B19200 }, { 38400, B38400 },
    { 57600, B57600 }, { 115200, B115200 },
#ifdef B500000
    { 500000, B500000 },
#endif
};

speed_t lms200_serial_speed(int baud)
{
    for (size_t i = 0; i < sizeof rates / sizeof rates[0]; i++)
        if (rates[i].baud == baud)
            return rates[i].speed;
    return 0;
}

int lms200_serial_baud(speed_t speed)
{
    for (size_t i = 0; i < sizeof rates / sizeof rates[0]; i++)
        if (rates[i].speed == speed)
            return rates[i].baud;
    return -1;
}

/* The line at baud; first_setup also makes it raw 8N1 without flow control, reads never
 * waiting. TCSANOW: the driver changes the rate only after the device answered at the old one
 * (or stayed silent), so nothing of ours is still in flight; waiting for a drain could block on
 * a line whose far end stopped reading. */
static int configure(int fd, int baud, bool first_setup)
{
    speed_t sp = lms200_serial_speed(baud);
    if (!sp)
        return marie_fail(EINVAL);
    struct termios t;
    if (tcgetattr(fd, &t) < 0)
        return -1;
    if (first_setup) {
        cfmakeraw(&t);
        t.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS);
        t.c_cflag |= CLOCAL | CREAD | CS8;
        t.c_iflag &= ~(IXON | IXOFF | IXANY);
        t.c_cc[VMIN] = 0;
        t.c_cc[VTIME] = 0;
    }
    cfsetispeed(&t, sp);
    cfsetospeed(&t, sp);
    if (tcsetattr(fd, TCSANOW, &t) < 0)
        return -1;
    tcflush(fd, TCIFLUSH);
    return 0;
}

int lms200_serial_setup(int fd, int baud)
{
    return configure(fd, baud, true);
}

int lms200_serial_open(const char *path)
{
    int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return -1;
    if (lms200_serial_setup(fd, 9600) < 0) {
        MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    return fd;
}

int lms200_serial_set_baud(int fd, int baud)
{
    return configure(fd, baud, false);
}

int lms200_serial_get_baud(int fd)
{
    struct termios t;
    if (tcgetattr(fd, &t) < 0)
        return -1;
    int b = lms200_serial_baud(cfgetospeed(&t));
    return b < 0 ? marie_fail(EINVAL) : b;
}

ssize_t lms200_serial_write(int fd, const void *buf, size_t len)
{
    size_t done = 0;
    while (done < len) {
        ssize_t n = write(fd, (const unsigned char *)buf + done, len - done);
        if (n > 0) {
            done += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && errno != EAGAIN)
            return -1;
        break;
    }
    return (ssize_t)done;
}
