/* mapsave: `marie map save NAME`: the map on the bus written as a map_server pair. */
#ifndef MARIE_MANAGERS_MAPSAVE_H
#define MARIE_MANAGERS_MAPSAVE_H

#ifdef __cplusplus
extern "C" {
#endif

/* argv[0] is "map". Returns a MARIE_EXIT_* status; messages go to stdout and stderr. */
int mapsave_cmd(const char *url, double timeout_s, int argc, char **argv);

#ifdef __cplusplus
}
#endif
#endif
