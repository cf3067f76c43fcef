/* map_updates_check LOG [COMPONENT...]: reads a recorded run's MAP (whole maps) and MAP_UPDATE
 * (changed rectangles) as a reader does (map/livemap), and at every whole map after
 * the first compares it with the map assembled from the one before and the updates since. Prints
 *   whole N updates M unmatched U refused R update_bytes B whole_bytes W compared C last_diff D
 * (D: cells of the last whole map in the frame of the one before, that differ from the map
 * assembled from it and the updates since; -1 if no whole map kept its frame: a map that grew
 * comes whole in its new frame, with nothing to compare it with), then
 *   final WIDTH HEIGHT occupied O known K
 * of the map assembled at the end (cells >= 65, cells >= 0), and for each COMPONENT the last
 * heartbeat's counters "NAME.COUNTER VALUE", one per line. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "map/livemap.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "lcmtypes/marie_types.h"
#include "core/lcmlog.h"

static struct {
    livemap_t live;
    int64_t whole, updates, unmatched, refused, update_bytes, whole_bytes, compared, last_diff;
    char **names;
    int nnames;
    marie_heartbeat_t *hb;      /* the last heartbeat of each name */
} R = { .last_diff = -1 };

static bool is(const lcmlog_event_t *ev, const char *ch)
{
    return ev->channel_len == strlen(ch) && memcmp(ev->channel, ch, ev->channel_len) == 0;
}

static void on_whole(const lcmlog_event_t *ev)
{
    marie_occupancy_grid_t g;
    char why[128];
    if (marie_decode_input(&marie_type_occupancy_grid_t, ev->data, ev->data_len, &g, NULL) != 0) {
        R.refused++;
        return;
    }
    R.whole++;
    R.whole_bytes += (int64_t)ev->data_len;
    const marie_occupancy_grid_t *h = &R.live.map;
    if (h->cells && h->width == g.width && h->height == g.height && h->origin.x == g.origin.x &&
        h->origin.y == g.origin.y) {
        R.compared++;
        R.last_diff = 0;
        for (int i = 0; i < g.ncells; i++)
            R.last_diff += h->cells[i] != g.cells[i];
    }
    if (getenv("MAP_UPDATES_VERBOSE"))
        fprintf(stderr, "whole %dx%d at (%g, %g) utime %" PRId64 ": diff %" PRId64 "\n", g.width, g.height, g.origin.x,
                g.origin.y, g.utime, R.last_diff);
    if (livemap_full(&R.live, &g, why, sizeof(why)) != 0) {
        fprintf(stderr, "map_updates_check: whole map refused: %s\n", why);
        R.refused++;
    }
    marie_type_occupancy_grid_t.decode_cleanup(&g);
}

static void on_update(const lcmlog_event_t *ev)
{
    marie_occupancy_grid_update_t u;
    char why[128];
    if (marie_decode_input(&marie_type_occupancy_grid_update_t, ev->data, ev->data_len, &u, NULL) != 0) {
        R.refused++;
        return;
    }
    R.updates++;
    R.update_bytes += (int64_t)ev->data_len;
    int r = livemap_update(&R.live, &u, why, sizeof(why));
    if (r < 0) {
        fprintf(stderr, "map_updates_check: update refused: %s\n", why);
        R.refused++;
    } else if (r > 0) {
        R.unmatched++;
    }
    marie_type_occupancy_grid_update_t.decode_cleanup(&u);
}

static void on_heartbeat(const lcmlog_event_t *ev)
{
    marie_heartbeat_t hb;
    if (marie_decode_input(&marie_type_heartbeat_t, ev->data, ev->data_len, &hb, NULL) != 0)
        return;
    for (int i = 0; i < R.nnames; i++)
        if (strcmp(hb.component, R.names[i]) == 0) {
            marie_type_heartbeat_t.decode_cleanup(&R.hb[i]);
            R.hb[i] = hb;
            return;
        }
    marie_type_heartbeat_t.decode_cleanup(&hb);
}

static void on_event(void *user, const lcmlog_event_t *ev)
{
    (void)user;
    if (is(ev, "MAP"))
        on_whole(ev);
    else if (is(ev, "MAP_UPDATE"))
        on_update(ev);
    else if (is(ev, "MARIE_HEARTBEAT"))
        on_heartbeat(ev);
}

int main(int argc, char **argv)
{
    FILE *f = argc >= 2 ? fopen(argv[1], "rb") : NULL;
    if (!f) {
        fprintf(stderr, "usage: map_updates_check LOG [COMPONENT...]\n");
        return 2;
    }
    R.names = argv + 2;
    R.nnames = argc - 2;
    R.hb = calloc((size_t)R.nnames + 1, sizeof(*R.hb));
    lcmlog_parser_t *lp = lcmlog_parser_create(on_event, NULL, NULL);
    if (!lp || !R.hb)
        return 1;
    unsigned char buf[65536];
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, f)) > 0)
        if (lcmlog_parser_feed(lp, buf, got) < 0)
            return 1;
    lcmlog_parser_finish(lp);
    lcmlog_parser_destroy(lp);
    fclose(f);
    printf("whole %" PRId64 " updates %" PRId64 " unmatched %" PRId64 " refused %" PRId64 " update_bytes %" PRId64
           " whole_bytes %" PRId64 " compared %" PRId64 " last_diff %" PRId64 "\n",
           R.whole, R.updates, R.unmatched, R.refused, R.update_bytes, R.whole_bytes, R.compared, R.last_diff);
    const marie_occupancy_grid_t *m = &R.live.map;
    int occupied = 0, known = 0;
    for (int i = 0; m->cells && i < m->ncells; i++) {
        occupied += m->cells[i] >= 65;
        known += m->cells[i] >= 0;
    }
    printf("final %d %d occupied %d known %d\n", m->width, m->height, occupied, known);
    for (int i = 0; i < R.nnames; i++) {
        for (int k = 0; k < R.hb[i].ncounters; k++)
            printf("%s.%s %" PRId64 "\n", R.names[i], R.hb[i].counters[k].name, R.hb[i].counters[k].value);
        marie_type_heartbeat_t.decode_cleanup(&R.hb[i]);
    }
    free(R.hb);
    livemap_free(&R.live);
    return 0;
}
