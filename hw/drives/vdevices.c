/* vdevices: virtual drives and gyro sharing one CAN bus connection. */
#include "hw/drives/vdevices.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "hw/can/can.h"

struct vdevices {
    vdevices_cfg_t cfg;
    can_bus_t *bus;
    vdrive_t *drive[2];
    vgyro_t *gyro;
    vdevices_stats_t st;
};

void vdevices_cfg_default(vdevices_cfg_t *cfg) { *cfg = (vdevices_cfg_t)VDEVICES_DEFAULTS; }

/* Answers go on the bus. The devices never talk to each other (only to the master), so
 * there is no need to loop their frames back locally as a real bus would. */
static void route(vdevices_t *v, const struct can_frame *f, int n)
{
    for (int i = 0; i < n; i++)
        if (can_bus_write(v->bus, &f[i]) == 0)
            v->st.frames_out++;
        else
            v->st.frames_dropped++;
}

static void deliver(vdevices_t *v, const struct can_frame *f, int64_t now)
{
    struct can_frame tx[16];
    for (int i = 0; i < 2; i++)
        if (v->drive[i])
            route(v, tx, vdrive_feed(v->drive[i], f, now, tx, 16));
    if (v->gyro)
        route(v, tx, vgyro_feed(v->gyro, f, now, tx, 16));
}

vdevices_t *vdevices_create(const vdevices_cfg_t *cfg, int64_t now)
{
    if (!cfg->can || cfg->left < 0 || cfg->left > 127 || cfg->right < 0 || cfg->right > 127 || cfg->gyro < 0 ||
        cfg->gyro > 127)
        return marie_fail_null(EINVAL);
    vdevices_t *v = calloc(1, sizeof *v);
    if (!v)
        return NULL;
    v->cfg = *cfg;
    v->bus = can_bus_open(cfg->can);
    if (!v->bus)
        goto err;
    int64_t nodes[2] = { cfg->left, cfg->right };
    for (int i = 0; i < 2; i++) {
        if (!nodes[i])
            continue;
        vdrive_cfg_t dc = cfg->drive;
        dc.node = (uint8_t)nodes[i];
        dc.name = i == 0 ? "marie vdrive left" : "marie vdrive right";
        if (!(v->drive[i] = vdrive_create(&dc)))
            goto err;
    }
    if (cfg->gyro) {
        vgyro_cfg_t gc = cfg->vgyro;
        gc.node = (uint8_t)cfg->gyro;
        if (!(v->gyro = vgyro_create(&gc)))
            goto err;
    }
    struct can_frame tx[4];
    for (int i = 0; i < 2; i++)
        if (v->drive[i])
            route(v, tx, vdrive_boot(v->drive[i], now, tx, 4));
    if (v->gyro)
        route(v, tx, vgyro_boot(v->gyro, now, tx, 4));
    return v;
err:;
    int e = errno ? errno : ENOMEM;
    vdevices_destroy(v);
    errno = e;
    return NULL;
}

void vdevices_destroy(vdevices_t *v)
{
    if (!v)
        return;
    vdrive_destroy(v->drive[0]);
    vdrive_destroy(v->drive[1]);
    vgyro_destroy(v->gyro);
    can_bus_close(v->bus);
    free(v);
}

int vdevices_fd(const vdevices_t *v) { return can_bus_fd(v->bus); }

int vdevices_process(vdevices_t *v, int64_t now)
{
    int n = can_bus_flush(v->bus);      /* answers the bus server had no room for yet */
    if (n < 0)
        return n;
    n = 0;
    struct can_frame f;
    for (int k = 0; k < 1024; k++) {
        int r = can_bus_read(v->bus, &f);
        if (r < 0)
            return r;
        if (r == 0)
            break;
        v->st.frames_in++;
        canid_t id = f.can_id & CAN_SFF_MASK;
        if (!(f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) && (id == 0x080 || (id & 0x780) == 0x700))
            v->st.master_frames_in++;
        n++;
        deliver(v, &f, now);
    }
    return n;
}

int vdevices_tick(vdevices_t *v, double dt, int64_t now)
{
    struct can_frame tx[16];
    /* Frames already on the bus count before any deadline is judged: a host that ran a
     * batch of physics steps without polling must not take a live master for dead. */
    int rc = vdevices_process(v, now);
    if (rc < 0)
        return rc;
    for (int i = 0; i < 2; i++)
        if (v->drive[i]) {
            vdrive_step(v->drive[i], dt);
            route(v, tx, vdrive_poll(v->drive[i], now, tx, 16));
        }
    if (v->gyro) {
        if (!v->cfg.external_physics && v->drive[0] && v->drive[1] && v->cfg.track_width > 0)
            vgyro_set_rate(v->gyro, v->cfg.wheel_radius *
                                    (vdrive_velocity(v->drive[1]) - vdrive_velocity(v->drive[0])) /
                                    v->cfg.track_width);
        route(v, tx, vgyro_poll(v->gyro, now, tx, 16));
    }
    return 0;
}

vdrive_t *vdevices_drive(vdevices_t *v, int i) { return i >= 0 && i < 2 ? v->drive[i] : NULL; }
vgyro_t *vdevices_gyro(vdevices_t *v) { return v->gyro; }
const vdevices_stats_t *vdevices_stats(const vdevices_t *v) { return &v->st; }
