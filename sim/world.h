/* world: the simulator's physics (ODE): map walls, a differential-drive robot and its sensors. */
#ifndef SIM_WORLD_H
#define SIM_WORLD_H

#include <stdbool.h>
#include <stdint.h>

#include "sim/walls.h"
#include "sim/world_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* sim_params_t, the robot and sensor settings: declared in world.params.yaml; these are its
 * defaults, the values the drivers assume. */
void sim_params_default(sim_params_t *p);

typedef struct sim_world sim_world_t;

/* Build the world: one static box per merged wall rectangle, the robot at the start pose.
 * NULL with errno set on failure. The map may be freed afterwards. */
/* Length and width of the robot's chassis, m: what must fit where it starts. */
void sim_world_footprint(const sim_params_t *p, double *lx, double *ly);
sim_world_t *sim_world_create(const occmap_t *map, const sim_params_t *p);
void sim_world_destroy(sim_world_t *w);                 /* NULL is a no-op */

/* Commands. Body velocity is turned into wheel speeds (v = r (wr + wl) / 2,
 * omega = r (wr - wl) / track), clamped to max_wheel_speed and ramped at accel. */
void sim_world_set_velocity(sim_world_t *w, double v, double omega);
void sim_world_set_wheels(sim_world_t *w, double left, double right);   /* rad/s */
/* Pressed e-stop: the drives brake to zero and ignore commands until released. */
void sim_world_set_estop(sim_world_t *w, bool pressed);

/* Carry the robot to a pose (the kidnapped robot): it lands at rest, its wheels did not turn,
 * so odometry sees nothing. -1 (EINVAL) when the chassis would not stand free there. */
int sim_world_teleport(sim_world_t *w, double x, double y, double theta);

/* Advance one fixed step. */
void sim_world_step(sim_world_t *w);
int64_t sim_world_time_us(const sim_world_t *w);
int64_t sim_world_steps(const sim_world_t *w);
double sim_world_step_s(const sim_world_t *w);

/* Ground truth in the map frame, and the true body velocity. */
void sim_world_pose(const sim_world_t *w, double *x, double *y, double *theta);
void sim_world_velocity(const sim_world_t *w, double *v, double *omega);
/* Wall contacts in the last step (0 when the robot touches no wall). */
int sim_world_wall_contacts(const sim_world_t *w);
long sim_world_wall_boxes(const sim_world_t *w);

/* Sensors (each reading draws noise from the world's seeded generator). */
/* Fill ranges[laser_beams] from angle -fov/2 (right) to +fov/2 (left); a beam that hits
 * nothing reads laser_max. Returns the beam count. */
int sim_world_laser(sim_world_t *w, float *ranges, int n);
/* Ranges without noise (tests). */
int sim_world_laser_exact(sim_world_t *w, float *ranges, int n);
double sim_world_gyro(sim_world_t *w);                  /* rad/s, with noise and bias */
/* Cumulative wheel angles (rad, forward positive) and speeds (rad/s). */
void sim_world_wheels(const sim_world_t *w, double *left_angle, double *right_angle,
                      double *left_speed, double *right_speed);
/* Encoder counts of the wheel angles (wrapping at int32). */
void sim_world_encoders(const sim_world_t *w, int32_t *left, int32_t *right);
const sim_params_t *sim_world_params(const sim_world_t *w);

#ifdef __cplusplus
}
#endif
#endif
