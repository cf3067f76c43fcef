/* vdevices: the robot's CAN devices in one object: two virtual CiA 402 drives and a virtual
 * gyro attached to a CAN bus (emulated or SocketCAN). A simulator polls vdevices_fd(), calls
 * vdevices_process() when it is readable and vdevices_tick() every physics step; with
 * `external_physics` it reads vdrive_command() and writes vdrive_set_feedback() and
 * vgyro_set_rate() itself, otherwise ideal motors turn the wheels and the gyro sees the
 * yaw rate of the differential drive. */
#ifndef MARIE_HW_VDEVICES_H
#define MARIE_HW_VDEVICES_H

#include <stdbool.h>
#include <stdint.h>

#include "hw/drives/vdrive.h"
#include "hw/gyro/vgyro.h"
#include "hw/drives/vdevices_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* vdevices_cfg_t: declared in vdevices.params.yaml: the bus, the drives' and the gyro's node ids
 * (0: none), the geometry for the ideal yaw rate, both drives' settings (`drive`) and the
 * gyro's (`vgyro`), and external_physics, set by the simulator; VDEVICES_DEFAULTS and
 * marie-vcan-devices' options VDEVICES_CLI come with it. */

void vdevices_cfg_default(vdevices_cfg_t *cfg);

typedef struct vdevices vdevices_t;

vdevices_t *vdevices_create(const vdevices_cfg_t *cfg, int64_t now);   /* NULL with errno */
void vdevices_destroy(vdevices_t *v);
int vdevices_fd(const vdevices_t *v);
/* Read and answer every waiting frame, after the answers the emulated bus's server had no room
 * for before. Returns frames handled, or -1 with errno (EPIPE: bus gone). */
int vdevices_process(vdevices_t *v, int64_t now);
/* Read what waits on the bus, advance physics by dt seconds and send time-driven frames
 * (heartbeats, gyro samples, EMCY of lost heartbeats or RPDOs). 0, or -1 with errno as process. */
int vdevices_tick(vdevices_t *v, double dt, int64_t now);
vdrive_t *vdevices_drive(vdevices_t *v, int i);     /* 0 left, 1 right; NULL if absent */
vgyro_t *vdevices_gyro(vdevices_t *v);
typedef struct {
    uint64_t frames_in, frames_out;
    uint64_t frames_dropped;    /* frames the devices made that the bus refused (its queue full) */
    /* SYNC and heartbeat frames received: the master's periodic traffic (not its SDOs, nor
     * another master's requests), which a simulator paces itself on. */
    uint64_t master_frames_in;
} vdevices_stats_t;
const vdevices_stats_t *vdevices_stats(const vdevices_t *v);

#ifdef __cplusplus
}
#endif
#endif
