/* devices: device mode: the simulator's physics drives the virtual CAN drives and gyro and the
 * virtual LMS200 of hw/, so the real drivers run against it unchanged. */
#ifndef SIM_DEVICES_H
#define SIM_DEVICES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/loop.h"
#include "sim/devices_params.h"
#include "sim/world.h"

#ifdef __cplusplus
extern "C" {
#endif

/* sim_devices_cfg_t is generated from devices.params.yaml: can ("emu:PATH", the emulated bus, or
 * "can:IF", SocketCAN), can_serve, left_node, right_node, gyro_node, vgyro_bias (rad/s),
 * laser_link, laser_hz, driver_lag (sim s), driver_wait (wall s), laser_hold. The world gives the
 * devices its wheels, encoder resolution and gyro noise. */

typedef struct {
    uint64_t can_frames_in, can_frames_out;
    uint64_t can_dropped;       /* frames lost on the emulated bus: refused to a device, or a driver's queue full */
    int64_t laser_scans;
    int64_t driver_waits, driver_timeouts;
} sim_devices_stats_t;

typedef struct sim_devices sim_devices_t;

/* Open the bus (serving it if asked), boot the devices and create the pty; their fds join
 * `loop`. `now` is the simulated time in us, which is the devices' clock. NULL on failure
 * with a reason in err. The world must outlive the devices; its laser should have 361 beams
 * (both LMS200 resolutions are then exact). */
sim_devices_t *sim_devices_create(const sim_devices_cfg_t *cfg, sim_world_t *world, marie_loop_t *loop,
                                  int64_t now, char *err, size_t errlen);
void sim_devices_destroy(sim_devices_t *d);             /* NULL is a no-op; leaves the loop clean */

/* Around each physics step: the drives' motor commands go to the wheels before it; wheel
 * feedback, the true yaw rate and time-driven frames go out after it. */
void sim_devices_before_step(sim_devices_t *d);
void sim_devices_after_step(sim_devices_t *d, double dt, int64_t now);
/* Whether the step ending at `now` sends the laser's host a telegram (sim_devices_after_step
 * does): the simulator publishes that instant on the clock first, so the driver, which stamps
 * what it reads by the clock, stamps the scan when it left the device and not up to a clock
 * period earlier. */
bool sim_devices_laser_sends(const sim_devices_t *d, int64_t now);
/* Driver lockstep, asked before each step: false while the devices are more than driver_lag of
 * simulated time ahead of a driver: past the CAN master's last frame (marie-drives sends SYNC
 * and heartbeat every 20 ms), or since the laser's host has left bytes unread. So a driver that
 * lags in wall time (a loaded machine, a fast simulation) is never taken for dead on simulated
 * time, and its data never pile up. With laser_hold the world does not step at all while a
 * telegram is unread: the laser's driver then reads it with the clock at the instant it came
 * (the clock message of that instant is the newest sent) and stamps the scan exactly. A driver
 * lagging for driver_wait of wall time counts as gone (killed, frozen) until its next frame or
 * read, and the world runs on. */
bool sim_devices_may_step(sim_devices_t *d);
const sim_devices_stats_t *sim_devices_stats(sim_devices_t *d);
const char *sim_devices_laser_path(const sim_devices_t *d);   /* the pty slave */

#ifdef __cplusplus
}
#endif
#endif
