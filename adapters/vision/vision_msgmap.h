/* vision_msgmap: "message reading": tag ids mapped by configuration to messages and goals. */
#ifndef VISION_MSGMAP_H
#define VISION_MSGMAP_H

#include <stdbool.h>
#include <stddef.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One configured meaning of a tag:
 *   - id: 7                      # tag id in the detector's family (required)
 *     message: "dock ahead"      # event text (kind "tag_message")
 *     kind: dock                 # event kind, default "tag_message"
 *     severity: info             # debug | info | warn | error, default info
 *     goal: {x: 2.0, y: 1.0, theta: 0, tolerance: 0.2, priority: 1, name: dock, id: 3}
 * At least one of message and goal is required. */
typedef struct {
    int tag_id;
    char *text;             /* NULL: no event */
    char *kind;
    int severity;           /* marie_event_t SEV_* */
    bool has_goal;
    int goal_id;
    char *goal_name;
    double x, y, theta, tolerance;
    int priority;
} vision_msg_t;

typedef struct {
    vision_msg_t *items;
    size_t n;
} vision_msgmap_t;

/* Reads a sequence node (NULL: an empty map). Every problem is added to errs as
 * "file:line:col: ..."; returns 0, or -1 with errno EINVAL (then m is left empty). */
int vision_msgmap_parse(const marie_node_t *seq, vision_msgmap_t *m, marie_errors_t *errs);
const vision_msg_t *vision_msgmap_find(const vision_msgmap_t *m, int tag_id);
void vision_msgmap_clear(vision_msgmap_t *m);

#ifdef __cplusplus
}
#endif
#endif
