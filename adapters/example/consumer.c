/* example consumer: counts the producer's messages and the gaps in their numbering, and
 * takes notes (event_t) on an event port that holds them while the consumer is not running. */
#include "core/component.h"

typedef struct {
    int64_t last;
} consumer_t;

static void on_counter(marie_component_t *c, marie_port_t *port, const void *msg, const marie_msg_info_t *info)
{
    consumer_t *s = marie_component_user(c);
    const marie_counter_t *m = msg;
    marie_component_count(c, "received", 1);
    if (s->last && m->value > s->last + 1)
        marie_component_count(c, "gaps", m->value - s->last - 1);
    s->last = m->value;
}

static void on_note(marie_component_t *c, marie_port_t *port, const void *msg, const marie_msg_info_t *info)
{
    marie_component_count(c, "notes", 1);
}

static int init(marie_component_t *c)
{
    return marie_port_on_message(marie_port(c, "in"), on_counter) ||
           marie_port_on_message(marie_port(c, "notes"), on_note);
}

static const marie_port_spec_t ports[] = {
    {"in", &marie_type_counter_t, MARIE_IN, MARIE_PUSH, "EXAMPLE"},
    {"notes", &marie_type_event_t, MARIE_IN, MARIE_EVENT, "EXAMPLE_NOTES"},
    {0},
};
static const marie_component_def_t def = {
    .kind = "example-consumer", .ports = ports, .on_init = init,
};

int main(int argc, char **argv)
{
    consumer_t s = {0};
    return marie_main(&def, argc, argv, &s);
}
