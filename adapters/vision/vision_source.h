/* vision_source: camera frames from OpenCV: a V4L2 device, a video file or an image folder. */
#ifndef VISION_SOURCE_H
#define VISION_SOURCE_H

#include <stdbool.h>
#include <stddef.h>

#include "camera/vision_image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vision_source vision_source_t;

/* Opens a source named by `uri`:
 *   device:N | /dev/videoN      V4L2 camera (optionally device:N@WxH to ask for a size)
 *   video:PATH | PATH.{avi,mp4,mkv,mov,webm}   video file
 *   folder:PATH | a directory   images (png, jpg, jpeg, pgm, ppm, bmp, tif, tiff) in name order
 * With `loop`, files and folders start over at their end. NULL with a reason in err. */
vision_source_t *vision_source_open(const char *uri, bool loop, char *err, size_t errlen);
void vision_source_close(vision_source_t *s);      /* NULL is a no-op */

/* Reads the next frame as grey. 0, or -1 with errno ENODATA at the end of a file or folder,
 * EBADMSG for an unreadable image in a folder (skipped: the next read moves on), EIO when the
 * device or file fails. *why (may be NULL) says what went wrong. */
int vision_source_read(vision_source_t *s, vision_frame_t *f, const char **why);
/* Writes frames (all of the first one's size) as an MJPEG .avi video with OpenCV's own
 * encoder, for tests and demos. 0, or -1 with errno EINVAL or EIO. */
int vision_video_save(const char *path, const vision_frame_t *frames, int n, double fps);

/* A short description for logs: "folder:/x (12 images)". */
const char *vision_source_describe(const vision_source_t *s);

#ifdef __cplusplus
}
#endif
#endif
