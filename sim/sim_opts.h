/* sim_opts: marie-sim's parameters, declared once in sim_main.c's table (MARIE_PARAM_AT) and
 * read through this struct by the simulator's parts (camera, microphone array). */
#ifndef SIM_OPTS_H
#define SIM_OPTS_H

#include <stdbool.h>
#include <stdint.h>

#include "core/component.h"

typedef struct {
    const char *world;
    const char *mode;
    double speed;
    double lockstep;
    double lockstep_timeout;
    double lockstep_pose;
    double driver_lag;
    double driver_wait;
    int64_t seed;
    double step;
    int64_t start_utime;
    double start_x;
    double start_y;
    double start_theta;
    const char *start;
    double robot_radius;
    double wheel_radius;
    double track;
    int64_t ticks_per_rev;
    double accel;
    double estop_decel;
    double max_wheel_speed;
    double cmd_timeout;
    int64_t laser_beams;
    double laser_max;
    double laser_noise;
    double laser_x;
    double laser_hz;
    double gyro_noise;
    double gyro_bias;
    double encoders_hz;
    double gyro_hz;
    double estop_hz;
    double truth_hz;
    double clock_hz;
    bool estop;
    bool camera;
    double camera_hz;
    const char *camera_size;
    const char *can;
    bool can_serve;
    int64_t left_node;
    int64_t right_node;
    int64_t gyro_node;
    double vgyro_bias;
    const char *audio;
    const char *mics;
    int64_t audio_rate;
    int64_t audio_block;
    const char *laser_link;
} sim_opts_t;

static inline const sim_opts_t *sim_opts(const marie_component_t *c) { return marie_component_params(c); }

#endif
