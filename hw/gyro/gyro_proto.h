/* gyro_proto: the CANopen yaw-rate gyro as marie uses it: object dictionary and TPDO layout,
 * shared by the driver (gyro_ctl) and the virtual gyro (vgyro). See docs/hw/gyro.md. */
#ifndef MARIE_HW_GYRO_PROTO_H
#define MARIE_HW_GYRO_PROTO_H

#define GYRO_OBJ_RATE       0x2100  /* i32, yaw rate in micro-rad/s, counter-clockwise positive */
#define GYRO_OBJ_STATUS     0x2101  /* u8, 0 ok, else a fault code (GYRO_STATUS_*) */
#define GYRO_OBJ_COUNTER    0x2102  /* u8, sample counter, +1 per TPDO */
/* The TPDO's layout, a co_pdo_map_t initializer (hw/canopen/pdo.h): what the driver maps and
 * decodes, and the virtual gyro's power-on mapping. */
#define GYRO_TPDO_MAP { 0, 3, { { GYRO_OBJ_RATE, 0, 32 }, { GYRO_OBJ_STATUS, 0, 8 }, { GYRO_OBJ_COUNTER, 0, 8 } } }
#define GYRO_RATE_SCALE     1e-6    /* rad/s per unit */
#define GYRO_STATUS_OK          0
#define GYRO_STATUS_SATURATED   1
#define GYRO_STATUS_SENSOR_FAULT 2

#endif
