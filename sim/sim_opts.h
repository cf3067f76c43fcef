/* sim_opts: marie-sim's parameters, declared once in sim_main.c's table (MARIE_PARAM_AT) and
 * read through this struct by the simulator's parts (camera, microphone array). */
#ifndef SIM_OPTS_H
#define SIM_OPTS_H

#include <stdbool.h>
#include <stdint.h>

#include "core/component.h"
#include "sim/sim_params.h"

static inline const sim_opts_t *sim_opts(const marie_component_t *c) { return marie_component_params(c); }

#endif
