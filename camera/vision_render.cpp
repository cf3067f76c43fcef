/* vision_render: a synthetic pinhole camera that draws AprilTags at known 3D poses. */
#include "camera/vision_render.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "camera/vision_family.h"
#include "core/err.h"

struct vision_render {
    apriltag_family_t *fam = nullptr;
    int total = 0;          /* cells per side of the family's tag image */
    int border = 0;         /* cells per side of the black border (the tag size) */
    cv::Mat noise_table;    /* unit Gaussian noise for opts.noise_table, drawn once per size */
};

void vision_render_opts_default(vision_render_opts_t *o)
{
    std::memset(o, 0, sizeof *o);
    o->background = VISION_BG_FLAT;
    o->bg_level = 128;
    o->black = 20;
    o->white = 235;
    o->supersample = 3;
}

vision_render_t *vision_render_create(const char *family)
{
    apriltag_family_t *fam = vision_family_create(family);
    if (!fam)
        return nullptr;
    vision_render_t *r = new (std::nothrow) vision_render;
    if (!r) {
        vision_family_destroy(fam);
        errno = ENOMEM;
        return nullptr;
    }
    r->fam = fam;
    r->total = fam->total_width;
    r->border = fam->width_at_border;
    return r;
}

void vision_render_destroy(vision_render_t *r)
{
    if (!r)
        return;
    vision_family_destroy(r->fam);
    delete r;
}

int vision_render_ncodes(const vision_render_t *r) { return (int)r->fam->ncodes; }
int vision_render_total_cells(const vision_render_t *r) { return r->total; }
int vision_render_border_cells(const vision_render_t *r) { return r->border; }

int vision_render_tag_cells(const vision_render_t *r, int id, uint8_t *out, int stride)
{
    const apriltag_family_t *f = r->fam;
    if (id < 0 || (uint32_t)id >= f->ncodes || stride < r->total)
        return marie_fail(EINVAL);
    int T = r->total;
    for (int y = 0; y < T; y++)
        std::memset(out + (size_t)y * stride, 0, T);
    /* The paper-coloured ring: just outside the black border for classic families, just
     * inside it for the reversed-border ones (whose outer ring carries data bits). */
    int ring = f->width_at_border + (f->reversed_border ? 0 : 2);
    int r0 = (T - ring) / 2, r1 = r0 + ring - 1;
    for (int i = r0; i <= r1; i++) {
        out[(size_t)r0 * stride + i] = out[(size_t)r1 * stride + i] = 255;
        out[(size_t)i * stride + r0] = out[(size_t)i * stride + r1] = 255;
    }
    /* Data bits, most significant first, at (bit_x, bit_y) from the black border's corner;
     * the offsets are signed for families with bits outside the border. */
    int b0 = (T - f->width_at_border) / 2;
    uint64_t code = f->codes[id];
    for (uint32_t i = 0; i < f->nbits; i++) {
        if (!((code >> (f->nbits - 1 - i)) & 1))
            continue;
        int x = (int32_t)f->bit_x[i] + b0, y = (int32_t)f->bit_y[i] + b0;
        if (x >= 0 && x < T && y >= 0 && y < T)
            out[(size_t)y * stride + x] = 255;
    }
    return 0;
}

/* Homography from texture pixels (the tag image plus a one-cell quiet zone, one texel per
 * cell, texel centres at integers) to supersampled image pixels. */
static cv::Matx33d tag_homography(const vision_render_t *r, const vision_camera_t *cam, const vision_pose_t *p,
                                  double size, int ss)
{
    double cell = size / r->border;
    double off = -(1.0 + r->total / 2.0) + 0.5;     /* texel a -> x = (a + off) * cell */
    cv::Matx33d S(cell, 0, off * cell, 0, cell, off * cell, 0, 0, 1);
    /* A point (x, y, 0) of the tag plane lands at K [r1 r2 t] (x, y, 1). */
    cv::Matx33d P(p->R[0], p->R[1], p->t[0], p->R[3], p->R[4], p->t[1], p->R[6], p->R[7], p->t[2]);
    /* Supersampled pixel U covers u = (U + 0.5) / ss - 0.5. */
    cv::Matx33d K(ss * cam->fx, 0, ss * (cam->cx + 0.5) - 0.5, 0, ss * cam->fy, ss * (cam->cy + 0.5) - 0.5, 0, 0, 1);
    return K * P * S;
}

static void draw_background(cv::Mat &bg, const vision_render_opts_t *o, cv::RNG &rng)
{
    if (o->background == VISION_BG_IMAGE && o->bg_image) {
        cv::Mat(bg.rows, bg.cols, CV_8U, const_cast<uint8_t *>(o->bg_image)).copyTo(bg);
        return;
    }
    bg.setTo(o->bg_level);
    if (o->background == VISION_BG_GRADIENT) {
        for (int x = 0; x < bg.cols; x++) {
            int v = o->bg_level + (int)std::lround(80.0 * x / std::max(1, bg.cols - 1)) - 40;
            bg.col(x).setTo(std::clamp(v, 0, 255));
        }
    } else if (o->background == VISION_BG_CLUTTER) {
        int n = 12 + (int)rng.uniform(0, 12);
        for (int i = 0; i < n; i++) {
            cv::Point c(rng.uniform(0, bg.cols), rng.uniform(0, bg.rows));
            int s = rng.uniform(8, std::max(9, bg.cols / 5));
            int v = rng.uniform(0, 256);
            if (rng.uniform(0, 2))
                cv::rectangle(bg, c, c + cv::Point(s, rng.uniform(4, s + 5)), cv::Scalar(v), cv::FILLED);
            else
                cv::circle(bg, c, s / 2, cv::Scalar(v), cv::FILLED, cv::LINE_AA);
        }
    }
}

int vision_render_frame(vision_render_t *r, const vision_camera_t *cam, const vision_tag_t *tags, size_t n,
                        const vision_render_opts_t *o, uint8_t *out, int stride, int channels)
{
    vision_render_opts_t defaults;
    if (!o) {
        vision_render_opts_default(&defaults);
        o = &defaults;
    }
    const char *why;
    if (!r || !cam || !out || (n && !tags) || (channels != 1 && channels != 3) ||
        vision_camera_check(cam, &why) < 0 || stride < cam->width * channels)
        return marie_fail(EINVAL);
    int ss = std::clamp(o->supersample, 1, 8);
    int W = cam->width, H = cam->height;

    /* Far tags first so nearer ones cover them. */
    std::vector<size_t> order;
    for (size_t i = 0; i < n; i++) {
        if (tags[i].id < 0 || (uint32_t)tags[i].id >= r->fam->ncodes || !(tags[i].size > 0))
            return marie_fail(EINVAL);
        order.push_back(i);
    }
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return tags[a].pose.t[2] > tags[b].pose.t[2]; });

    int T = r->total + 2;
    cv::Mat tex(T, T, CV_8U), ones(T, T, CV_8U, cv::Scalar(255));
    cv::Mat ink, cover;        /* supersampled, made for the first tag in view */
    cv::Rect used;             /* union of the drawn tags' regions, supersampled */
    cv::Rect frame(0, 0, W * ss, H * ss);
    int drawn = 0;
    for (size_t k : order) {
        const vision_tag_t *tg = &tags[k];
        /* Every texture corner must be in front of the camera for the homography to hold. */
        double half = tg->size / r->border * T / 2, zmin = 1e300;
        for (int c = 0; c < 4; c++) {
            double in[3] = { (c & 1) ? half : -half, (c & 2) ? half : -half, 0 }, p[3];
            vision_pose_apply(&tg->pose, in, p);
            zmin = std::min(zmin, p[2]);
        }
        if (zmin < 1e-3)
            continue;
        cv::Matx33d Hm = tag_homography(r, cam, &tg->pose, tg->size, ss);
        std::vector<cv::Point2d> src = { { -0.5, -0.5 }, { T - 0.5, -0.5 }, { T - 0.5, T - 0.5 }, { -0.5, T - 0.5 } }, dst;
        cv::perspectiveTransform(src, dst, cv::Matx33d(Hm));
        double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
        for (auto &q : dst) {
            x0 = std::min(x0, q.x); y0 = std::min(y0, q.y);
            x1 = std::max(x1, q.x); y1 = std::max(y1, q.y);
        }
        if (x1 < 0 || y1 < 0 || x0 >= frame.width || y0 >= frame.height)
            continue;
        cv::Rect roi = cv::Rect((int)std::floor(std::max(x0, 0.0)), (int)std::floor(std::max(y0, 0.0)),
                                (int)std::ceil(std::min(x1, (double)frame.width)) - (int)std::floor(std::max(x0, 0.0)) + 1,
                                (int)std::ceil(std::min(y1, (double)frame.height)) - (int)std::floor(std::max(y0, 0.0)) + 1) & frame;
        if (roi.empty())
            continue;
        uint8_t cells[64 * 64];
        if (T - 2 > 64)
            return marie_fail(EINVAL);
        if (ink.empty()) {
            ink = cv::Mat(H * ss, W * ss, CV_8U, cv::Scalar(0));
            cover = cv::Mat(H * ss, W * ss, CV_8U, cv::Scalar(0));
        }
        vision_render_tag_cells(r, tg->id, cells, 64);
        tex.setTo(o->white);
        /* Seen from behind (its z axis, into the tag, points back at the camera) a tag is
         * blank paper. */
        const double *R = tg->pose.R, *t = tg->pose.t;
        bool front = R[2] * t[0] + R[5] * t[1] + R[8] * t[2] > 0;
        for (int y = 0; front && y < T - 2; y++)
            for (int x = 0; x < T - 2; x++)
                tex.at<uint8_t>(y + 1, x + 1) = cells[y * 64 + x] ? o->white : o->black;
        cv::Matx33d shift(1, 0, -roi.x, 0, 1, -roi.y, 0, 0, 1);
        cv::Mat Hroi(shift * Hm);
        cv::Mat inkroi = ink(roi), coverroi = cover(roi);
        cv::warpPerspective(tex, inkroi, Hroi, roi.size(), cv::INTER_NEAREST, cv::BORDER_TRANSPARENT);
        cv::warpPerspective(ones, coverroi, Hroi, roi.size(), cv::INTER_NEAREST, cv::BORDER_TRANSPARENT);
        used = drawn ? (used | roi) : roi;
        drawn++;
    }

    cv::RNG rng(o->seed ? o->seed : 0x9e3779b9u);
    cv::Mat bg(H, W, CV_8U);
    draw_background(bg, o, rng);
    cv::Mat inkf, coverf, bgf, img;
    bg.convertTo(bgf, CV_32F);
    img = bgf;
    if (drawn) {
        /* Only the output pixels the tags touch are composited (whole pixels of ss x ss). */
        int px0 = used.x / ss, py0 = used.y / ss;
        int px1 = std::min(W, (used.x + used.width + ss - 1) / ss), py1 = std::min(H, (used.y + used.height + ss - 1) / ss);
        cv::Rect out_r(px0, py0, px1 - px0, py1 - py0), in_r(px0 * ss, py0 * ss, out_r.width * ss, out_r.height * ss);
        ink(in_r).convertTo(inkf, CV_32F);
        cover(in_r).convertTo(coverf, CV_32F, 1.0 / 255);
        /* Premultiplied ink averages correctly over a pixel's subsamples. */
        inkf = inkf.mul(coverf);
        cv::resize(inkf, inkf, out_r.size(), 0, 0, cv::INTER_AREA);
        cv::resize(coverf, coverf, out_r.size(), 0, 0, cv::INTER_AREA);
        cv::Mat part = img(out_r);
        cv::Mat mixed = inkf + part.mul(1.0 - coverf);
        mixed.copyTo(part);
    }
    if (o->blur_sigma > 0)
        cv::GaussianBlur(img, img, cv::Size(0, 0), o->blur_sigma);
    if (o->noise_sigma > 0 && o->noise_table) {
        /* A window of a larger field, placed by the seed: a tenth of the cost of drawing. */
        cv::Mat &tab = r->noise_table;
        if (tab.rows != 2 * H || tab.cols != 2 * W) {
            tab.create(2 * H, 2 * W, CV_32F);
            cv::RNG trng(0x5eed);
            trng.fill(tab, cv::RNG::NORMAL, 0, 1);
        }
        cv::Mat win = tab(cv::Rect((int)rng.uniform(0, W), (int)rng.uniform(0, H), W, H));
        cv::scaleAdd(win, o->noise_sigma, img, img);
    } else if (o->noise_sigma > 0) {
        cv::Mat noise(H, W, CV_32F);
        rng.fill(noise, cv::RNG::NORMAL, 0, o->noise_sigma);
        img += noise;
    }
    cv::Mat gray;
    img.convertTo(gray, CV_8U);     /* rounds and saturates */
    for (int y = 0; y < H; y++) {
        const uint8_t *s = gray.ptr<uint8_t>(y);
        uint8_t *d = out + (size_t)y * stride;
        if (channels == 1) {
            std::memcpy(d, s, W);
        } else {
            for (int x = 0; x < W; x++)
                d[3 * x] = d[3 * x + 1] = d[3 * x + 2] = s[x];
        }
    }
    return drawn;
}

int vision_render_world(vision_render_t *r, const vision_camera_t *cam, const vision_pose_t *cam_in_world,
                        const vision_tag_t *tags, size_t n, const vision_render_opts_t *o,
                        uint8_t *out, int stride, int channels)
{
    if (!cam_in_world || (n && !tags))
        return marie_fail(EINVAL);
    vision_pose_t world_in_cam;
    vision_pose_inverse(cam_in_world, &world_in_cam);
    std::vector<vision_tag_t> local(tags, tags + n);
    for (auto &t : local)
        vision_pose_compose(&world_in_cam, &t.pose, &t.pose);
    return vision_render_frame(r, cam, local.data(), n, o, out, stride, channels);
}
