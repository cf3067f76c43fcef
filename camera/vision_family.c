/* vision_family: the AprilTag families libapriltag ships, looked up by name. */
#include "camera/vision_family.h"

#include <errno.h>
#include <string.h>

#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include "core/err.h"

static const struct {
    const char *name;
    apriltag_family_t *(*create)(void);
    void (*destroy)(apriltag_family_t *);
} families[] = {
    { "tag36h11", tag36h11_create, tag36h11_destroy },
    { "tag36h10", tag36h10_create, tag36h10_destroy },
    { "tag25h9", tag25h9_create, tag25h9_destroy },
    { "tag16h5", tag16h5_create, tag16h5_destroy },
    { "tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy },
    { "tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy },
    { "tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy },
    { "tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy },
    { "tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy },
};
#define NFAM (sizeof families / sizeof families[0])

static const char *const names[NFAM + 1] = {
    "tag36h11", "tag36h10", "tag25h9", "tag16h5", "tagCircle21h7", "tagCircle49h12",
    "tagCustom48h12", "tagStandard41h12", "tagStandard52h13", NULL,
};

apriltag_family_t *vision_family_create(const char *name)
{
    for (size_t i = 0; name && i < NFAM; i++)
        if (strcmp(families[i].name, name) == 0) {
            apriltag_family_t *f = families[i].create();
            if (!f)
                errno = ENOMEM;
            return f;
        }
    return marie_fail_null(ENOENT);
}

void vision_family_destroy(apriltag_family_t *fam)
{
    if (!fam)
        return;
    for (size_t i = 0; i < NFAM; i++)
        if (strcmp(families[i].name, fam->name) == 0) {
            families[i].destroy(fam);
            return;
        }
}

const char *const *vision_family_names(void)
{
    return names;
}
