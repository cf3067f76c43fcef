/* vision_image: marie.image_t (raw or JPEG) to and from grey frames, checking every field. */
#include "adapters/vision/vision_image.h"

#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <csetjmp>
#include <cstring>
#include <vector>

#include <jpeglib.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

void vision_frame_free(vision_frame_t *f)
{
    free(f->data);
    std::memset(f, 0, sizeof *f);
}

int vision_frame_reserve(vision_frame_t *f, int width, int height)
{
    size_t need = (size_t)width * height;
    if (need > f->cap) {
        uint8_t *d = (uint8_t *)realloc(f->data, need);
        if (!d)
            return -ENOMEM;
        f->data = d;
        f->cap = need;
    }
    f->width = width;
    f->height = height;
    f->stride = width;
    return 0;
}

int vision_frame_save(const vision_frame_t *f, const char *path)
{
    try {
        cv::Mat m(f->height, f->width, CV_8UC1, f->data, f->stride);
        return cv::imwrite(path, m) ? 0 : -EIO;
    } catch (const cv::Exception &) {
        return -EIO;
    }
}

static thread_local char why_buf[160];

static int bad(const char **why, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int bad(const char **why, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why_buf, sizeof why_buf, fmt, ap);
    va_end(ap);
    if (why)
        *why = why_buf;
    return -EBADMSG;
}

/* JPEG goes through libjpeg itself rather than cv::imdecode: libjpeg's warnings (a stream
 * cut short, scrambled entropy data) become a refusal instead of a grey-padded frame and a
 * line on stderr per frame, and the decoder writes grey rows straight into the frame. */
struct jpeg_err {
    struct jpeg_error_mgr pub;
    jmp_buf jb;
    int warnings;
    char msg[JMSG_LENGTH_MAX];
};

static void jpeg_on_error(j_common_ptr ci)
{
    jpeg_err *e = (jpeg_err *)ci->err;
    ci->err->format_message(ci, e->msg);
    longjmp(e->jb, 1);
}

static void jpeg_on_message(j_common_ptr ci, int level)
{
    jpeg_err *e = (jpeg_err *)ci->err;
    if (level < 0 && e->warnings++ == 0)
        ci->err->format_message(ci, e->msg);
}

/* No C++ objects with destructors live in this frame: longjmp leaves it. */
static int decode_jpeg(const marie_image_t *img, vision_frame_t *f, const char **why)
{
    const uint8_t *d = (const uint8_t *)img->data;
    if (img->size < 4)
        return bad(why, "JPEG image: only %d bytes", img->size);
    if (d[0] != 0xff || d[1] != 0xd8)
        return bad(why, "JPEG image: no start-of-image marker");
    struct jpeg_decompress_struct ci;
    jpeg_err err;
    std::memset(&err, 0, sizeof err);
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
        return -ENOMEM;
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
        return -ENOMEM;
    cv::Mat src(h, w, ch == 1 ? CV_8UC1 : CV_8UC3, (void *)img->data, img->row_stride);
    cv::Mat dst(h, w, CV_8UC1, f->data, f->stride);
    if (ch == 1)
        src.copyTo(dst);
    else
        cv::cvtColor(src, dst, img->format == MARIE_IMAGE_T_FORMAT_RGB8 ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
    return 0;
}

int vision_image_encode(const uint8_t *pix, int width, int height, int stride, int channels, int format,
                        int quality, int64_t utime, marie_image_t *img)
{
    if (!pix || width <= 0 || height <= 0 || (channels != 1 && channels != 3) || stride < width * channels)
        return -EINVAL;
    std::memset(img, 0, sizeof *img);
    img->utime = utime;
    img->width = width;
    img->height = height;
    if (format == MARIE_IMAGE_T_FORMAT_JPEG) {
        cv::Mat src(height, width, channels == 1 ? CV_8UC1 : CV_8UC3, (void *)pix, stride), bgr;
        if (channels == 3)
            cv::cvtColor(src, bgr, cv::COLOR_RGB2BGR);
        std::vector<uint8_t> out;
        try {
            if (!cv::imencode(".jpg", channels == 3 ? bgr : src, out,
                              { cv::IMWRITE_JPEG_QUALITY, quality < 1 ? 1 : quality > 100 ? 100 : quality }))
                return -EINVAL;
        } catch (const cv::Exception &) {
            return -EINVAL;
        }
        img->data = (uint8_t *)malloc(out.size() ? out.size() : 1);
        if (!img->data)
            return -ENOMEM;
        std::memcpy(img->data, out.data(), out.size());
        img->size = (int32_t)out.size();
        img->format = MARIE_IMAGE_T_FORMAT_JPEG;
        return 0;
    }
    if (format == MARIE_IMAGE_T_FORMAT_GRAY8 && channels != 1)
        return -EINVAL;
    if ((format == MARIE_IMAGE_T_FORMAT_RGB8 || format == MARIE_IMAGE_T_FORMAT_BGR8) && channels != 3)
        return -EINVAL;
    if (format != MARIE_IMAGE_T_FORMAT_GRAY8 && format != MARIE_IMAGE_T_FORMAT_RGB8 &&
        format != MARIE_IMAGE_T_FORMAT_BGR8)
        return -EINVAL;
    size_t row = (size_t)width * channels;
    img->data = (uint8_t *)malloc(row * height);
    if (!img->data)
        return -ENOMEM;
    for (int y = 0; y < height; y++)
        std::memcpy(img->data + row * y, pix + (size_t)stride * y, row);
    img->row_stride = (int32_t)row;
    img->size = (int32_t)(row * height);
    img->format = (int8_t)format;
    if (format == MARIE_IMAGE_T_FORMAT_BGR8)     /* pixels come in as RGB */
        for (size_t i = 0; i < row * height; i += 3) {
            uint8_t t = img->data[i];
            img->data[i] = img->data[i + 2];
            img->data[i + 2] = t;
        }
    return 0;
}
