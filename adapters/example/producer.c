/* example producer: publishes a numbered counter_t at a fixed rate; the smallest useful component. */
#include "adapters/example/producer_params.h"
#include "core/component.h"

typedef struct {
    int64_t seq;
} producer_t;

static void tick(marie_component_t *c, int64_t overruns)
{
    producer_t *p = marie_component_user(c);
    const producer_params_t *q = marie_component_params(c);
    marie_counter_t msg = {.name = (char *)q->label, .value = ++p->seq};
    marie_port_publish(marie_port(c, "out"), &msg);
}

/* rate_hz may change at run time (marie param set): the same timer, at the new rate. */
static int rate_changed(marie_component_t *c, const char *name)
{
    const producer_params_t *q = marie_component_params(c);
    if (q->rate_hz <= 0 || q->rate_hz > 10000) {
        marie_component_fail_reason(c, "rate_hz must be in (0, 10000]");
        return -1;
    }
    return marie_component_every(c, q->rate_hz, tick) ? 0 : -1;
}

static int init(marie_component_t *c)
{
    return rate_changed(c, "rate_hz") < 0 ? -1 : marie_component_on_param(c, "rate_hz", rate_changed);
}

static const marie_port_spec_t ports[] = {
    {"out", &marie_type_counter_t, MARIE_OUT, MARIE_PUSH, "EXAMPLE"},
    {0},
};
static const marie_param_spec_t params[] = PRODUCER_PARAMS;
static const marie_component_def_t def = {
    .kind = "example-producer", .ports = ports, .params = params, .params_size = sizeof(producer_params_t),
    .on_init = init,
};

int main(int argc, char **argv)
{
    producer_t p = {0};
    return marie_main(&def, argc, argv, &p);
}
