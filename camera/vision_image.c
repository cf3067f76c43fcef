/* vision_image: marie.image_t (raw or JPEG) to grey frames, checking every field. Plain C on
 * libjpeg so that the fuzz target needs nothing else. */
#include "camera/vision_image.h"

#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>
#include "core/err.h"
#include "core/log.h"

void vision_frame_free(vision_frame_t *f)
{
    free(f->data);
    memset(f, 0, sizeof *f);
}

int vision_frame_reserve(vision_frame_t *f, int width, int height)
{
    size_t need = (size_t)width * height;
    if (need > f->cap) {
        uint8_t *d = realloc(f->data, need);
        if (!d)
            return marie_fail(ENOMEM);
        f->data = d;
        f->cap = need;
    }
    f->width = width;
    f->height = height;
    f->stride = width;
    return 0;
}

static __thread char why_buf[160];

static int bad(const char **why, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int bad(const char **why, const char *fmt, ...)
{
    MARIE_VFORMAT(why_buf, fmt);
    if (why)
        *why = why_buf;
    return marie_fail(EBADMSG);
}

/* libjpeg's warnings (a stream cut short, scrambled entropy data) become a refusal instead of
 * a grey-padded frame and a line on stderr per frame. */
typedef struct {
    struct jpeg_error_mgr pub;
    jmp_buf jb;
    int warnings;
    char msg[JMSG_LENGTH_MAX];
} jpeg_err_t;

static void jpeg_on_error(j_common_ptr ci)
{
    jpeg_err_t *e = (jpeg_err_t *)ci->err;
    ci->err->format_message(ci, e->msg);
    longjmp(e->jb, 1);
}

static void jpeg_on_message(j_common_ptr ci, int level)
{
    jpeg_err_t *e = (jpeg_err_t *)ci->err;
    if (level < 0 && e->warnings++ == 0)
        ci->err->format_message(ci, e->msg);
}

static int decode_jpeg(const marie_image_t *img, vision_frame_t *f, const char **why)
{
    const uint8_t *d = img->data;
    if (img->size < 4)
        return bad(why, "JPEG image: only %d bytes", img->size);
    if (d[0] != 0xff || d[1] != 0xd8)
        return bad(why, "JPEG image: no start-of-image marker");
    struct jpeg_decompress_struct ci;
    jpeg_err_t err;
    memset(&err, 0, sizeof err);
    ci.err = jpeg_std_error(&err.pub);
    err.pub.error_exit = jpeg_on_error;
    err.pub.emit_message = jpeg_on_message;
    jpeg_create_decompress(&ci);
    if (setjmp(err.jb)) {
        jpeg_destroy_decompress(&ci);
        return bad(why, "JPEG image: corrupt data: %s", err.msg);
    }
    jpeg_mem_src(&ci, d, (unsigned long)img->size);
    jpeg_read_header(&ci, TRUE);
    int w = (int)ci.image_width, h = (int)ci.image_height;
    if (w <= 0 || h <= 0 || w > VISION_IMAGE_MAX_SIDE || h > VISION_IMAGE_MAX_SIDE) {
        jpeg_destroy_decompress(&ci);
        return bad(why, "JPEG image: %dx%d is out of range", w, h);
    }
    if ((img->width || img->height) && (w != img->width || h != img->height)) {
        jpeg_destroy_decompress(&ci);
        return bad(why, "JPEG image: decodes to %dx%d but the message says %dx%d", w, h, img->width, img->height);
    }
    if (vision_frame_reserve(f, w, h) < 0) {
        jpeg_destroy_decompress(&ci);
        return marie_fail(ENOMEM);
    }
    ci.out_color_space = JCS_GRAYSCALE;
    jpeg_start_decompress(&ci);
    while (ci.output_scanline < ci.output_height) {
        JSAMPROW row = f->data + (size_t)ci.output_scanline * f->stride;
        jpeg_read_scanlines(&ci, &row, 1);
    }
    jpeg_finish_decompress(&ci);
    jpeg_destroy_decompress(&ci);
    if (err.warnings)
        return bad(why, "JPEG image: corrupt data: %s", err.msg);
    return 0;
}

int vision_image_decode(const marie_image_t *img, vision_frame_t *f, const char **why)
{
    int w = img->width, h = img->height;
    if (img->size < 0 || (img->size > 0 && !img->data))
        return bad(why, "image: size %d without data", img->size);
    if (img->format == MARIE_IMAGE_T_FORMAT_JPEG)
        return decode_jpeg(img, f, why);
    int ch;
    switch (img->format) {
    case MARIE_IMAGE_T_FORMAT_GRAY8: ch = 1; break;
    case MARIE_IMAGE_T_FORMAT_RGB8:
    case MARIE_IMAGE_T_FORMAT_BGR8: ch = 3; break;
    default: return bad(why, "image: unknown format %d", img->format);
    }
    if (w <= 0 || h <= 0 || w > VISION_IMAGE_MAX_SIDE || h > VISION_IMAGE_MAX_SIDE)
        return bad(why, "image: bad size %dx%d", w, h);
    if (img->row_stride < w * ch)
        return bad(why, "image: row_stride %d is less than width %d x %d bytes", img->row_stride, w, ch);
    int64_t need = (int64_t)img->row_stride * (h - 1) + (int64_t)w * ch;
    if (img->size < need)
        return bad(why, "image: %d bytes of data, %dx%d with stride %d needs %lld", img->size, w, h,
                   img->row_stride, (long long)need);
    if (vision_frame_reserve(f, w, h) < 0)
        return marie_fail(ENOMEM);
    /* Luma with the fixed-point weights OpenCV uses (0.299, 0.587, 0.114 in 1/16384). */
    int r = img->format == MARIE_IMAGE_T_FORMAT_RGB8 ? 0 : 2, b = 2 - r;
    for (int y = 0; y < h; y++) {
        const uint8_t *s = img->data + (size_t)img->row_stride * y;
        uint8_t *o = f->data + (size_t)f->stride * y;
        if (ch == 1) {
            memcpy(o, s, (size_t)w);
            continue;
        }
        for (int x = 0; x < w; x++, s += 3)
            o[x] = (uint8_t)((s[r] * 4899 + s[1] * 9617 + s[b] * 1868 + 8192) >> 14);
    }
    return 0;
}
