/* vision_source: camera frames from OpenCV: a V4L2 device, a video file or an image folder. */
#include "adapters/vision/vision_source.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <dirent.h>
#include <strings.h>
#include <sys/stat.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "core/err.h"

namespace {
enum class Kind { Device, Video, Folder };
}

struct vision_source {
    Kind kind = Kind::Folder;
    bool loop = false;
    std::string path, desc, why;
    cv::VideoCapture cap;
    std::vector<std::string> files;
    size_t next = 0;
    cv::Mat frame, gray;
};

static bool has_suffix(const std::string &s, const char *const *exts)
{
    size_t dot = s.rfind('.');
    if (dot == std::string::npos)
        return false;
    for (; *exts; exts++)
        if (strcasecmp(s.c_str() + dot + 1, *exts) == 0)
            return true;
    return false;
}

static const char *const image_exts[] = { "png", "jpg", "jpeg", "pgm", "ppm", "pnm", "bmp", "tif", "tiff", nullptr };
static const char *const video_exts[] = { "avi", "mp4", "mkv", "mov", "webm", "mjpeg", nullptr };

static vision_source_t *fail(vision_source_t *s, char *err, size_t errlen, const std::string &msg)
{
    snprintf(err, errlen, "%s", msg.c_str());
    delete s;
    return nullptr;
}

static bool is_number(const std::string &s)
{
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

vision_source_t *vision_source_open(const char *uri, bool loop, char *err, size_t errlen)
{
    auto *s = new (std::nothrow) vision_source;
    if (!s) {
        snprintf(err, errlen, "out of memory");
        return nullptr;
    }
    s->loop = loop;
    std::string u = uri ? uri : "";
    struct stat st;
    if (u.rfind("device:", 0) == 0 || u.rfind("/dev/video", 0) == 0) {
        s->kind = Kind::Device;
        std::string dev = u.rfind("device:", 0) == 0 ? u.substr(7) : u;
        int w = 0, h = 0;
        size_t at = dev.find('@');
        if (at != std::string::npos) {
            if (sscanf(dev.c_str() + at + 1, "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0)
                return fail(s, err, errlen, "camera '" + u + "': size after @ must be WxH");
            dev = dev.substr(0, at);
        }
        bool ok;
        try {
            ok = is_number(dev) ? s->cap.open(std::stoi(dev), cv::CAP_V4L2) : s->cap.open(dev, cv::CAP_V4L2);
        } catch (const cv::Exception &e) {
            ok = false;
        }
        if (!ok || !s->cap.isOpened())
            return fail(s, err, errlen, "camera '" + u + "' cannot be opened (no such V4L2 device, or busy)");
        /* The newest frame, not one queued while the loop was busy detecting. */
        s->cap.set(cv::CAP_PROP_BUFFERSIZE, 1);
        if (w) {
            s->cap.set(cv::CAP_PROP_FRAME_WIDTH, w);
            s->cap.set(cv::CAP_PROP_FRAME_HEIGHT, h);
        }
        s->desc = "device:" + dev;
        return s;
    }
    if (u.rfind("folder:", 0) == 0 || (u.rfind("video:", 0) != 0 && stat(u.c_str(), &st) == 0 && S_ISDIR(st.st_mode))) {
        s->kind = Kind::Folder;
        s->path = u.rfind("folder:", 0) == 0 ? u.substr(7) : u;
        DIR *d = opendir(s->path.c_str());
        if (!d)
            return fail(s, err, errlen, "image folder '" + s->path + "': " + strerror(errno));
        while (struct dirent *e = readdir(d))
            if (e->d_name[0] != '.' && has_suffix(e->d_name, image_exts))
                s->files.push_back(s->path + "/" + e->d_name);
        closedir(d);
        std::sort(s->files.begin(), s->files.end());
        if (s->files.empty())
            return fail(s, err, errlen, "image folder '" + s->path + "' holds no images");
        s->desc = "folder:" + s->path + " (" + std::to_string(s->files.size()) + " images)";
        return s;
    }
    if (u.rfind("video:", 0) == 0 || has_suffix(u, video_exts)) {
        s->kind = Kind::Video;
        s->path = u.rfind("video:", 0) == 0 ? u.substr(6) : u;
        if (stat(s->path.c_str(), &st) != 0)
            return fail(s, err, errlen, "video file '" + s->path + "': " + strerror(errno));
        /* FFmpeg, then OpenCV's own MJPEG reader; letting OpenCV probe every backend
         * (GStreamer, depth cameras over USB) is slow and leaks in those libraries. */
        bool ok = false;
        for (int api : { (int)cv::CAP_FFMPEG, (int)cv::CAP_OPENCV_MJPEG }) {
            try {
                ok = s->cap.open(s->path, api) && s->cap.isOpened();
            } catch (const cv::Exception &) {
                ok = false;
            }
            if (ok)
                break;
        }
        if (!ok || !s->cap.isOpened())
            return fail(s, err, errlen, "video file '" + s->path + "' cannot be decoded");
        s->desc = "video:" + s->path;
        return s;
    }
    return fail(s, err, errlen, "camera source '" + u + "': expected device:N, /dev/videoN, video:FILE or folder:DIR");
}

void vision_source_close(vision_source_t *s)
{
    delete s;
}

const char *vision_source_describe(const vision_source_t *s)
{
    return s->desc.c_str();
}

static int to_frame(const cv::Mat &m, vision_frame_t *f)
{
    cv::Mat g;
    if (m.channels() == 3)
        cv::cvtColor(m, g, cv::COLOR_BGR2GRAY);
    else if (m.channels() == 4)
        cv::cvtColor(m, g, cv::COLOR_BGRA2GRAY);
    else
        g = m;
    if (g.depth() != CV_8U)
        g.convertTo(g, CV_8U, g.depth() == CV_16U ? 1.0 / 256 : 1.0);
    if (vision_frame_reserve(f, g.cols, g.rows) < 0)
        return marie_fail(ENOMEM);
    for (int y = 0; y < g.rows; y++)
        std::memcpy(f->data + (size_t)y * f->stride, g.ptr<uint8_t>(y), g.cols);
    return 0;
}

int vision_source_read(vision_source_t *s, vision_frame_t *f, const char **why)
{
    if (s->kind == Kind::Folder) {
        if (s->next >= s->files.size()) {
            if (!s->loop) {
                if (why)
                    *why = "end of the image folder";
                return marie_fail(ENODATA);
            }
            s->next = 0;
        }
        const std::string &p = s->files[s->next++];
        cv::Mat m;
        try {
            m = cv::imread(p, cv::IMREAD_UNCHANGED);
        } catch (const cv::Exception &) {
            m.release();
        }
        if (m.empty() || m.cols > VISION_IMAGE_MAX_SIDE || m.rows > VISION_IMAGE_MAX_SIDE) {
            s->why = "image '" + p + "' cannot be read";
            if (why)
                *why = s->why.c_str();
            return marie_fail(EBADMSG);
        }
        return to_frame(m, f);
    }
    bool ok;
    try {
        ok = s->cap.read(s->frame);
    } catch (const cv::Exception &) {
        ok = false;
    }
    if (!ok || s->frame.empty()) {
        if (s->kind == Kind::Video) {
            if (s->loop && s->cap.set(cv::CAP_PROP_POS_FRAMES, 0) && s->cap.read(s->frame) && !s->frame.empty())
                return to_frame(s->frame, f);
            if (why)
                *why = "end of the video file";
            return marie_fail(ENODATA);
        }
        if (why)
            *why = "camera stopped delivering frames";
        return marie_fail(EIO);
    }
    return to_frame(s->frame, f);
}

int vision_video_save(const char *path, const vision_frame_t *frames, int n, double fps)
{
    if (!path || !frames || n <= 0 || !(fps > 0))
        return marie_fail(EINVAL);
    try {
        cv::Size size(frames[0].width, frames[0].height);
        cv::VideoWriter w(path, cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, size, true);
        if (!w.isOpened())
            return marie_fail(EIO);
        for (int i = 0; i < n; i++) {
            if (frames[i].width != size.width || frames[i].height != size.height)
                return marie_fail(EINVAL);
            /* Grey MJPEG from OpenCV's encoder is not read back cleanly by FFmpeg: write colour. */
            cv::Mat bgr;
            cv::cvtColor(cv::Mat(size, CV_8UC1, frames[i].data, frames[i].stride), bgr, cv::COLOR_GRAY2BGR);
            w.write(bgr);
        }
    } catch (const cv::Exception &) {
        return marie_fail(EIO);
    }
    return 0;
}
