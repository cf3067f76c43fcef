/* vision_image_encode: grey or RGB pixels to marie.image_t (raw, or JPEG through OpenCV). */
#include "camera/vision_image.h"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/err.h"

int vision_frame_save(const vision_frame_t *f, const char *path)
{
    try {
        cv::Mat m(f->height, f->width, CV_8UC1, f->data, f->stride);
        return cv::imwrite(path, m) ? 0 : marie_fail(EIO);
    } catch (const cv::Exception &) {
        return marie_fail(EIO);
    }
}

int vision_image_encode(const uint8_t *pix, int width, int height, int stride, int channels, int format,
                        int quality, int64_t utime, marie_image_t *img)
{
    if (!pix || width <= 0 || height <= 0 || (channels != 1 && channels != 3) || stride < width * channels)
        return marie_fail(EINVAL);
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
                return marie_fail(EINVAL);
        } catch (const cv::Exception &) {
            return marie_fail(EINVAL);
        }
        img->data = (uint8_t *)malloc(out.size() ? out.size() : 1);
        if (!img->data)
            return marie_fail(ENOMEM);
        std::memcpy(img->data, out.data(), out.size());
        img->size = (int32_t)out.size();
        img->format = MARIE_IMAGE_T_FORMAT_JPEG;
        return 0;
    }
    if (format == MARIE_IMAGE_T_FORMAT_GRAY8 && channels != 1)
        return marie_fail(EINVAL);
    if ((format == MARIE_IMAGE_T_FORMAT_RGB8 || format == MARIE_IMAGE_T_FORMAT_BGR8) && channels != 3)
        return marie_fail(EINVAL);
    if (format != MARIE_IMAGE_T_FORMAT_GRAY8 && format != MARIE_IMAGE_T_FORMAT_RGB8 &&
        format != MARIE_IMAGE_T_FORMAT_BGR8)
        return marie_fail(EINVAL);
    size_t row = (size_t)width * channels;
    img->data = (uint8_t *)malloc(row * height);
    if (!img->data)
        return marie_fail(ENOMEM);
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
