/* serial: raw termios setup and baud switching for the LMS200 line; works on ttys and ptys. */
#ifndef MARIE_HW_LMS200_SERIAL_H
#define MARIE_HW_LMS200_SERIAL_H

#include <stddef.h>
#include <sys/types.h>
#include <termios.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Open a serial device non-blocking, raw 8N1 without flow control, at 9600 baud (the
 * LMS200's rate after power-up). Returns the fd, or -1 with errno. */
int lms200_serial_open(const char *path);
/* Put an already open fd into the same raw mode at `baud`. 0, or -1 with errno. */
int lms200_serial_setup(int fd, int baud);
/* Change the line speed (input and output) and drop unread input. 0, or -1 with errno
 * (EINVAL for a rate without a Bxxx constant). */
int lms200_serial_set_baud(int fd, int baud);
/* The fd's current output speed in baud, or -1 with errno. */
int lms200_serial_get_baud(int fd);
/* Bxxx constant <-> baud; 0 / -1 when unknown. */
speed_t lms200_serial_speed(int baud);
int lms200_serial_baud(speed_t speed);
/* Write as much of buf as the line takes now, without waiting: bytes written (0 when its
 * buffer is full; the caller keeps the rest and polls for POLLOUT), or -1 with errno. */
ssize_t lms200_serial_write(int fd, const void *buf, size_t len);

#ifdef __cplusplus
}
#endif
#endif
