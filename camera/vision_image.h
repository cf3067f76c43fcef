/* vision_image: camera frames as 8-bit grey buffers, and marie.image_t (raw or JPEG) to and
 * from them with every malformed field caught. */
#ifndef VISION_IMAGE_H
#define VISION_IMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_image_t.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Largest accepted side, to bound memory on a bad header. */
#define VISION_IMAGE_MAX_SIDE 8192

/* A grey frame owned by the caller; data grows as needed and is freed by vision_frame_free. */
typedef struct {
    int width, height, stride;
    uint8_t *data;
    size_t cap;
} vision_frame_t;

void vision_frame_free(vision_frame_t *f);
/* Makes room for width x height (stride = width). 0, or -1 with errno ENOMEM. */
int vision_frame_reserve(vision_frame_t *f, int width, int height);

/* Writes a frame to an image file, the format chosen by the extension (png, jpg, pgm...).
 * 0, or -1 with errno EIO. */
int vision_frame_save(const vision_frame_t *f, const char *path);

/* Decodes a marie.image_t (GRAY8, RGB8, BGR8 or JPEG) into grey. 0, or -1 with errno EBADMSG with a
 * reason (static text or one formatted into the thread's buffer) in *why. */
int vision_image_decode(const marie_image_t *img, vision_frame_t *f, const char **why);

/* Fills *img from pixels (channels 1: grey, 3: RGB) as raw (GRAY8 / RGB8) or JPEG with
 * `quality` 1..100. img->data is malloc'd: free it with free(). 0, or -1 with errno EINVAL or ENOMEM. */
int vision_image_encode(const uint8_t *pix, int width, int height, int stride, int channels, int format,
                        int quality, int64_t utime, marie_image_t *img);

#ifdef __cplusplus
}
#endif
#endif
