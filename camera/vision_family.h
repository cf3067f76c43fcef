/* vision_family: the AprilTag families libapriltag ships, looked up by name. */
#ifndef VISION_FAMILY_H
#define VISION_FAMILY_H

#include <apriltag/apriltag.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A new family object by name ("tag36h11", ...); NULL with errno = ENOENT if unknown.
 * Free with vision_family_destroy(). A family object serves one detector only. */
apriltag_family_t *vision_family_create(const char *name);
void vision_family_destroy(apriltag_family_t *fam);     /* NULL is a no-op */
/* Names, NULL-terminated. */
const char *const *vision_family_names(void);

#ifdef __cplusplus
}
#endif
#endif
