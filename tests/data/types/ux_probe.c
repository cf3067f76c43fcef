/* ux_probe: a user's C component on a user's type (tests/tools/test_user_types.sh compiles it
 * outside marie's build, against marie-types-gen's output): publishes ux.reading_t on `out` at
 * rate_hz and counts the readings its `in` port accepts. */
#include "core/component.h"
#include "lcmtypes/ux_types.h"

static void on_reading(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    const ux_reading_t *r = msg;
    marie_component_count(c, "received", 1);
    if (r->n == 3 && r->samples[2] == 3.0f)
        marie_component_count(c, "intact", 1);
}

static void tick(marie_component_t *c, int64_t overruns)
{
    static float samples[3] = {1, 2, 3};
    static int64_t seq;
    ux_reading_t r = {.utime = ++seq, .sensor = "thermo", .value = 21.5, .n = 3, .samples = samples,
                      .where = {.x = 1, .y = 2, .theta = 0.5}};
    marie_port_publish(marie_port(c, "out"), &r);
}

static int init(marie_component_t *c)
{
    return marie_port_on_message(marie_port(c, "in"), on_reading) || !marie_component_every(c, 20, tick);
}

static const marie_port_spec_t ports[] = {
    {"out", &marie_type_ux_reading_t, MARIE_OUT, MARIE_PUSH, "READING"},
    {"in", &marie_type_ux_reading_t, MARIE_IN, MARIE_PUSH, "READING_ECHO"},
    {0},
};
static const marie_component_def_t def = {.kind = "ux-probe", .ports = ports, .on_init = init};

int main(int argc, char **argv) { return marie_main(&def, argc, argv, NULL); }
