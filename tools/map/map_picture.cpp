// map_picture: a built map with the estimated and the reference trajectories drawn over it (PNG).
#include "tools/map/map_tool.h"

#include <cmath>
#include <exception>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {

uint8_t grey(int8_t v)
{
    if (v < 0 || v > 100)
        return 205;
    return v >= 65 ? 0 : v < 20 ? 254 : 205;
}

}  // namespace

extern "C" int map_picture_write(const char *path, const occmap_t *m, const traj_pose_t *est, const traj_pose_t *ref,
                                 size_t n, const double align[3])
{
    try {
        cv::Mat img(m->height, m->width, CV_8UC3);
        for (int y = 0; y < m->height; y++)
            for (int x = 0; x < m->width; x++) {
                uint8_t g = grey(m->cells[(size_t)y * m->width + x]);
                img.at<cv::Vec3b>(m->height - 1 - y, x) = cv::Vec3b(g, g, g);     // row 0 at the top: y up
            }
        // The reference into the map's frame: est = align^-1 (+) ref.
        const double c = std::cos(align[2]), s = std::sin(align[2]);
        auto pixel = [&](double x, double y) {
            return cv::Point((int)std::floor((x - m->origin_x) / m->resolution),
                             m->height - 1 - (int)std::floor((y - m->origin_y) / m->resolution));
        };
        std::vector<cv::Point> e, r;
        for (size_t i = 0; i < n; i++) {
            double dx = ref[i].x - align[0], dy = ref[i].y - align[1];
            r.push_back(pixel(c * dx + s * dy, -s * dx + c * dy));
            e.push_back(pixel(est[i].x, est[i].y));
        }
        cv::polylines(img, r, false, cv::Scalar(0, 160, 0), 1, cv::LINE_AA);
        cv::polylines(img, e, false, cv::Scalar(0, 0, 220), 1, cv::LINE_AA);
        return cv::imwrite(path, img) ? 0 : -1;
    } catch (const std::exception &) {
        return -1;
    }
}
