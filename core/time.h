/* time: monotonic and wall microseconds; the component clock (wall or simulated) lives in loop.h. */
#ifndef MARIE_TIME_H
#define MARIE_TIME_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

int64_t marie_mono_us(void);   /* CLOCK_MONOTONIC */
int64_t marie_wall_us(void);   /* CLOCK_REALTIME, the utime of LCM messages */

#ifdef __cplusplus
}
#endif
#endif
