/* bench_vision: AprilTag detection rate at 640x480 on one core through marie-vision against
 * libapriltag called directly in the same run, and image transport (640x480 RGB, 30 Hz) over
 * LCM: latency and loss. Prints "bench metric value unit baseline ratio" rows. */
#include <errno.h>
#include <math.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <apriltag/apriltag.h>
#include <apriltag/apriltag_pose.h>
#include <apriltag/tag36h11.h>
#include <lcm/lcm.h>

#include "adapters/vision/vision_component.h"
#include "adapters/vision/vision_detect.h"
#include "bench/bench.h"
#include "camera/vision_image.h"
#include "camera/vision_render.h"
#include "core/loop.h"
#include "core/time.h"

#define W 640
#define H 480
#define NFRAMES 8
static const vision_camera_t cam = { W, H, 500.0, 500.0, 319.5, 239.5 };
static uint8_t frames[NFRAMES][W * H];

/* A typical scene: three tags at 1-3 m, tilted, over clutter, with noise and blur. */
static void make_frames(void)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.background = VISION_BG_CLUTTER;
    o.noise_sigma = 4;
    o.blur_sigma = 0.8;
    for (int f = 0; f < NFRAMES; f++) {
        vision_tag_t t[3];
        for (int i = 0; i < 3; i++) {
            t[i].id = 10 * f + i;
            t[i].size = 0.16;
            vision_rot_rpy(0.3 * sin(f + i), 0.4 * cos(f * 2 + i), 0.5 * f, t[i].pose.R);
            t[i].pose.t[0] = -0.6 + 0.6 * i;
            t[i].pose.t[1] = 0.1 * (f % 3) - 0.1;
            t[i].pose.t[2] = 1.0 + 0.25 * ((f + i) % 5);
        }
        o.seed = 100 + f;
        vision_render_frame(r, &cam, t, 3, &o, frames[f], W, 1);
    }
    vision_render_destroy(r);
}

static void row(const char *metric, double v, const char *unit, double base, bool has_base)
{
    bench_row("vision", metric, v, unit, has_base ? base : NAN);
}

/* ---- libapriltag directly: detect and estimate each tag's pose ---- */
static int lib_frame(apriltag_detector_t *td, int f)
{
    image_u8_t im = { W, H, W, frames[f] };
    zarray_t *dets = apriltag_detector_detect(td, &im);
    int n = zarray_size(dets);
    for (int i = 0; i < n; i++) {
        apriltag_detection_t *d;
        zarray_get(dets, i, &d);
        apriltag_detection_info_t info = { d, 0.16, cam.fx, cam.fy, cam.cx + 0.5, cam.cy + 0.5 };
        apriltag_pose_t p;
        estimate_tag_pose(&info, &p);
        free(p.R);      /* matd_destroy is not exported by Debian's build; a matd_t is one block */
        free(p.t);
    }
    apriltag_detections_destroy(dets);
    return n;
}

/* ---- marie-vision: image_t in over LCM, tag_detections_t out over LCM ---- */
static int got;
static int got_tags;
static void on_det(const lcm_recv_buf_t *rb, const char *ch, const marie_tag_detections_t *m, void *u)
{
    got++;
    got_tags += m->count;
}

typedef struct {
    marie_component_t *c;
    lcm_t *bus;
    marie_image_t img[NFRAMES];
} adapter_t;

static int answered(void *want) { return got >= *(int *)want; }

/* The bench's bus is one more fd of the component's loop: one loop serves both sides. */
static int adapter_frame(adapter_t *a, int f)
{
    int want = got + 1, before = got_tags;
    marie_image_t_publish(a->bus, VISION_CH_IMAGE, &a->img[f]);
    if (marie_loop_run_until(marie_component_loop(a->c), 2000, answered, &want) != 1)
        return -1;
    return got_tags - before;
}

static void bench_detection(double seconds)
{
    apriltag_family_t *fam = tag36h11_create();
    apriltag_detector_t *td = apriltag_detector_create();
    apriltag_detector_add_family_bits(td, fam, 2);
    td->quad_decimate = 2.0;
    td->quad_sigma = 0.0;
    td->nthreads = 1;
    td->refine_edges = 1;

    adapter_t a = { 0 };
    char *argv[] = { "marie-vision", "--param", "fx=500", "--param", "fy=500", "--param", "cx=319.5",
                     "--param", "cy=239.5", "--param", "width=640", "--param", "height=480",
                     "--param", "messages=[{id: 1, message: one}]", NULL };
    marie_errors_t errs = { 0 };
    a.c = marie_component_create(&vision_component_def, (int)(sizeof argv / sizeof argv[0]) - 1, argv, NULL, &errs);
    const char *why;
    if (!a.c || marie_component_command(a.c, MARIE_CMD_INIT, &why) < 0 ||
        marie_component_command(a.c, MARIE_CMD_START, &why) < 0) {
        marie_errors_print(&errs, stderr);
        fprintf(stderr, "bench_vision: cannot start marie-vision\n");
        exit(1);
    }
    a.bus = lcm_create(marie_default_url());
    if (!a.bus || marie_loop_add_bus(marie_component_loop(a.c), a.bus, 16) < 0) {
        fprintf(stderr, "bench_vision: no LCM\n");
        exit(1);
    }
    marie_tag_detections_t_subscribe(a.bus, VISION_CH_DETECTIONS, on_det, NULL);
    for (int f = 0; f < NFRAMES; f++)
        vision_image_encode(frames[f], W, H, W, 1, MARIE_IMAGE_T_FORMAT_GRAY8, 0, 1 + f, &a.img[f]);
    /* Warm up both paths, then alternate short rounds so both see the same machine load. */
    for (int f = 0; f < NFRAMES; f++) {
        lib_frame(td, f);
        adapter_frame(&a, f);
    }
    double lib_s = 0, ad_s = 0;
    long lib_frames = 0, ad_frames = 0, lib_tags = 0, ad_tags = 0, lost = 0;
    int64_t stop = marie_mono_us() + (int64_t)(seconds * 1e6);
    while (marie_mono_us() < stop) {
        int64_t t0 = marie_mono_us();
        for (int f = 0; f < NFRAMES; f++)
            lib_tags += lib_frame(td, f);
        int64_t t1 = marie_mono_us();
        for (int f = 0; f < NFRAMES; f++) {
            int n = adapter_frame(&a, f);
            if (n < 0)
                lost++;
            else
                ad_tags += n;
        }
        int64_t t2 = marie_mono_us();
        lib_s += (t1 - t0) / 1e6;
        ad_s += (t2 - t1) / 1e6;
        lib_frames += NFRAMES;
        ad_frames += NFRAMES;
    }
    row("detect_640x480_library_frames_per_s", lib_frames / lib_s, "frames/s", 0, false);
    row("detect_640x480_library_detections_per_s", lib_tags / lib_s, "det/s", 0, false);
    row("detect_640x480_adapter_frames_per_s", ad_frames / ad_s, "frames/s", lib_frames / lib_s, true);
    row("detect_640x480_adapter_detections_per_s", ad_tags / ad_s, "det/s", lib_tags / lib_s, true);
    row("detect_640x480_adapter_frames_unanswered", (double)lost, "frames", 0, false);
    for (int f = 0; f < NFRAMES; f++)
        free(a.img[f].data);
    marie_loop_remove_bus(marie_component_loop(a.c), a.bus);
    lcm_destroy(a.bus);
    marie_component_destroy(a.c);
    apriltag_detector_destroy(td);
    tag36h11_destroy(fam);
}

/* ---- range: how far a 0.16 m tag is read at 640x480, f = 500 px, per decimation ---- */
static void bench_range(int per_distance)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.noise_sigma = 3;
    o.blur_sigma = 0.6;
    static uint8_t img[W * H];
    static const double dist[] = { 2, 4, 6, 8 };
    for (int dec = 2; dec >= 1; dec--) {
        vision_detector_opts_t dopts;
        vision_detector_opts_default(&dopts);
        dopts.decimate = dec;
        vision_detector_t *d = vision_detector_create(&dopts, NULL, 0);
        for (size_t k = 0; k < sizeof dist / sizeof dist[0]; k++) {
            int hit = 0;
            for (int i = 0; i < per_distance; i++) {
                vision_tag_t t = { .id = i, .size = 0.16 };
                /* Spread over the view and over tilts of up to 30 degrees. */
                vision_rot_rpy(0.5 * sin(i * 1.7), 0.5 * cos(i * 2.3), i * 0.9, t.pose.R);
                t.pose.t[0] = dist[k] * 0.4 * sin(i * 0.7);
                t.pose.t[1] = dist[k] * 0.25 * cos(i * 1.1);
                t.pose.t[2] = dist[k];
                o.seed = 500 + i;
                vision_render_frame(r, &cam, &t, 1, &o, img, W, 1);
                vision_detection_t det[2];
                int n = vision_detector_detect(d, img, W, H, W, det, 2, NULL);
                hit += n >= 1 && det[0].id == i;
            }
            char m[96];
            snprintf(m, sizeof m, "range_tag0.16m_decimate%d_at_%gm_detected", dec, dist[k]);
            row(m, 100.0 * hit / per_distance, "%", 0, false);
        }
        vision_detector_destroy(d);
    }
    vision_render_destroy(r);
}

/* ---- transport: a child publishes 640x480 RGB at 30 Hz, the parent receives ---- */
static int64_t lat[4096];
static int nlat;
static void on_img(const lcm_recv_buf_t *rb, const char *ch, const marie_image_t *m, void *u)
{
    const vision_frame_t *scratch = u;
    (void)scratch;
    if (nlat < 4096)
        lat[nlat++] = marie_wall_us() - m->utime;
}

static int cmp64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* burst: the frames go out back to back while the receiver sleeps (a consumer busy with a
 * slow frame): what the socket and LCM's own buffers can hold. */
static void transport(const char *label, const char *url, int format, int count, bool burst)
{
    nlat = 0;
    lcm_t *rx = lcm_create(url);
    marie_loop_t *loop = marie_loop_create();
    if (!rx || !loop || marie_loop_add_bus(loop, rx, 64) < 0) {
        fprintf(stderr, "bench_vision: cannot open %s\n", url);
        marie_loop_destroy(loop);
        if (rx)
            lcm_destroy(rx);
        return;
    }
    marie_image_t_subscription_t *sub = marie_image_t_subscribe(rx, "BENCH_IMAGE", on_img, NULL);
    pid_t pid = fork();
    if (pid == 0) {
        lcm_t *tx = lcm_create(url);
        static uint8_t rgb[W * H * 3];
        for (size_t i = 0; i < sizeof rgb; i++)
            rgb[i] = (uint8_t)(frames[0][i / 3] + (i % 3) * 20);
        usleep(200000);     /* let the receiver settle */
        int64_t next = marie_mono_us();
        for (int i = 0; i < count; i++) {
            next += 1000000 / 30;
            int64_t wait = next - marie_mono_us();
            if (wait > 0 && !burst)
                usleep((useconds_t)wait);
            marie_image_t img;
            vision_image_encode(rgb, W, H, W * 3, 3, format, 90, 0, &img);
            /* Stamped as it is handed to LCM: the latency is LCM's encode, the UDP fragments
             * over loopback, reassembly, decode and delivery to the handler. */
            img.utime = marie_wall_us();
            marie_image_t_publish(tx, "BENCH_IMAGE", &img);
            free(img.data);
        }
        lcm_destroy(tx);
        _exit(0);
    }
    if (burst)
        usleep(700000);
    marie_loop_run_until(loop, (int)(count / 30.0 * 1000) + 1500, NULL, NULL);
    waitpid(pid, NULL, 0);
    while (marie_loop_run_once(loop, 100) > 0)     /* until 100 ms pass without a frame */
        ;
    marie_image_t_unsubscribe(rx, sub);
    marie_loop_destroy(loop);
    lcm_destroy(rx);
    char m[128];
    snprintf(m, sizeof m, "transport_%s_lost", label);
    row(m, count - nlat, "frames", count, false);
    printf("# %s: %d of %d frames arrived\n", label, nlat, count);
    if (nlat == 0)
        return;
    qsort(lat, nlat, sizeof lat[0], cmp64);
    if (burst)
        return;
    int under = 0;
    for (int i = 0; i < nlat; i++)
        under += lat[i] < 1000;
    snprintf(m, sizeof m, "transport_%s_under_1ms", label);
    row(m, 100.0 * under / nlat, "%", 0, false);
    snprintf(m, sizeof m, "transport_%s_latency_p50", label);
    row(m, lat[nlat / 2] / 1000.0, "ms", 0, false);
    snprintf(m, sizeof m, "transport_%s_latency_p99", label);
    row(m, lat[(int)ceil(0.99 * nlat) - 1] / 1000.0, "ms", 0, false);
    snprintf(m, sizeof m, "transport_%s_latency_max", label);
    row(m, lat[nlat - 1] / 1000.0, "ms", 0, false);
}

int main(int argc, char **argv)
{
    /* Detection on one core: pinned to the CPU we start on. */
    cpu_set_t all, set;
    sched_getaffinity(0, sizeof all, &all);
    CPU_ZERO(&set);
    CPU_SET(sched_getcpu() < 0 ? 0 : sched_getcpu(), &set);
    sched_setaffinity(0, sizeof set, &set);
    marie_log_set_threshold(MARIE_LOG_WARN);
    make_frames();
    bench_detection(getenv("BENCH_QUICK") ? 2.0 : 6.0);
    bench_range(getenv("BENCH_QUICK") ? 8 : 24);
    /* Publisher and receiver are separate processes, as on the robot: free to use any core. */
    sched_setaffinity(0, sizeof all, &all);

    /* What the kernel grants for marie's recv_buf_size (capped by net.core.rmem_max). */
    int fd = socket(AF_INET, SOCK_DGRAM, 0), want = 8388608, have = 0;
    socklen_t len = sizeof have;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &want, sizeof want);
    getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &have, &len);
    close(fd);
    row("udp_recv_buffer_granted_for_8MB", have, "bytes", 0, false);

    int n = getenv("BENCH_QUICK") ? 60 : 300;
    transport("rgb640x480_30hz_raw", MARIE_DEFAULT_URL, MARIE_IMAGE_T_FORMAT_RGB8, n, false);
    transport("rgb640x480_30hz_jpeg", MARIE_DEFAULT_URL, MARIE_IMAGE_T_FORMAT_JPEG, n, false);
    transport("rgb640x480_burst8_sleeping_receiver", MARIE_DEFAULT_URL, MARIE_IMAGE_T_FORMAT_RGB8, 8, true);
    /* Contrast: the kernel's default receive buffer. */
    transport("rgb640x480_30hz_raw_default_rcvbuf", "udpm://239.255.76.67:7667?ttl=0", MARIE_IMAGE_T_FORMAT_RGB8,
              n / 5, false);
    return 0;
}
