/* test_ports: push ports carry typed messages, mistyped payloads are counted and dropped,
 * pull ports get the newest value from a server speaking the Mailbox protocol, or time out;
 * a channel the system file puts on shared memory carries 900 KB messages whole. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/component.h"
#include "tests/proc.h"
#include "tests/fails.h"

static const marie_port_spec_t tx_ports[] = {
    {"pose", &marie_type_pose_cov_t, MARIE_OUT, MARIE_PUSH, "T_POSE"},
    {"raw", NULL, MARIE_OUT, MARIE_PUSH, "T_POSE"},
    {0},
};
static const marie_component_def_t tx_def = {.kind = "tx", .ports = tx_ports};

typedef struct {
    int got;
    marie_pose2d_t last;
    char frame[16];
} rx_state_t;

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    rx_state_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    s->got++;
    s->last = m->pose;
    snprintf(s->frame, sizeof s->frame, "%s", m->frame);
    assert_string_equal(info->channel, "T_POSE");
}

static int rx_init(marie_component_t *c)
{
    return marie_port_on_message(marie_port(c, "pose"), on_pose);
}

static const marie_port_spec_t rx_ports[] = {
    {"pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "T_POSE"},
    {"latest", &marie_type_pose_cov_t, MARIE_IN, MARIE_PULL, "T_LATEST"},
    {0},
};
static const marie_component_def_t rx_def = {.kind = "rx", .ports = rx_ports, .on_init = rx_init};

static marie_component_t *started(const marie_component_def_t *def, int argc, char **argv, void *user)
{
    marie_errors_t e = {0};
    marie_component_t *c = marie_component_create(def, argc, argv, user, &e);
    marie_errors_print(&e, stderr);
    assert_non_null(c);
    const char *why;
    assert_int_equal(marie_component_command(c, MARIE_CMD_INIT, &why), 0);
    assert_int_equal(marie_component_command(c, MARIE_CMD_START, &why), 0);
    return c;
}

static marie_component_t *make(const marie_component_def_t *def, const char *name, void *user)
{
    return started(def, 3, (char *[]){(char *)def->kind, "--name", (char *)name}, user);
}

/* One of the system file's components. */
static marie_component_t *make_in(const char *file, const marie_component_def_t *def, const char *name, void *user)
{
    return started(def, 5, (char *[]){(char *)def->kind, "--system", (char *)file, "--name", (char *)name}, user);
}

static void spin(marie_component_t **cs, int n, int ms)
{
    int64_t end = marie_mono_us() + ms * 1000LL;
    while (marie_mono_us() < end)
        for (int i = 0; i < n; i++)
            marie_loop_run_once(marie_component_loop(cs[i]), 5);
}

static void push_delivers_typed_messages_and_drops_mistyped_ones(void **state)
{
    rx_state_t s = {0};
    marie_component_t *cs[2] = {make(&tx_def, "tx", NULL), make(&rx_def, "rx", &s)};
    marie_pose_cov_t m = {.utime = 1, .frame = "map", .pose = {1.5, -2.0, 0.25}};
    for (int i = 0; i < 3; i++) {
        m.pose.x = i;
        assert_int_equal(marie_port_publish(marie_port(cs[0], "pose"), &m), 0);
    }
    spin(cs, 2, 300);
    assert_int_equal(s.got, 3);
    assert_true(s.last.x == 2.0 && s.last.y == -2.0 && s.last.theta == 0.25);
    assert_string_equal(s.frame, "map");
    /* A payload of another type on the same channel: counted, never delivered. */
    marie_counter_t other = {.name = "x", .value = 1};
    uint8_t buf[64];
    int len = marie_counter_t_encode(buf, 0, sizeof buf, &other);
    assert_int_equal(marie_port_publish_raw(marie_port(cs[0], "raw"), buf, (size_t)len), 0);
    /* The right fingerprint over a truncated body: counted as undecodable. */
    uint8_t full[256];
    marie_pose_cov_t_encode(full, 0, sizeof full, &m);
    assert_int_equal(marie_port_publish_raw(marie_port(cs[0], "raw"), full, 20), 0);
    /* A complete payload whose string lost its NUL (lcm-gen would read past it): refused. */
    int flen = marie_pose_cov_t_encode(full, 0, sizeof full, &m);
    full[23] = 'x';  /* "map\0" sits at 20..23, after fingerprint, utime and its length */
    assert_int_equal(marie_port_publish_raw(marie_port(cs[0], "raw"), full, (size_t)flen), 0);
    /* Well formed but not finite (a NaN heading, an infinite covariance): refused. */
    m.pose.theta = NAN;
    assert_int_equal(marie_port_publish(marie_port(cs[0], "pose"), &m), 0);
    m.pose.theta = 0;
    m.cov[4] = INFINITY;
    assert_int_equal(marie_port_publish(marie_port(cs[0], "pose"), &m), 0);
    spin(cs, 2, 300);
    assert_int_equal(s.got, 3);
    assert_int_equal(marie_component_counter(cs[1], "bad_fingerprint"), 1);
    assert_int_equal(marie_component_counter(cs[1], "bad_payload"), 2);
    assert_int_equal(marie_component_counter(cs[1], "bad_nonfinite"), 2);
    marie_component_destroy(cs[0]);
    marie_component_destroy(cs[1]);
}

/* A minimal server of the pull protocol on T_LATEST.PULL (what a Mailbox does). */
typedef struct {
    lcm_t *lcm;
    int requests;
    int answer;     /* 0: keep silent, 1: answer with a pose, 2: answer empty */
} server_t;

static void on_request(const lcm_recv_buf_t *rb, const char *ch, const marie_pull_request_t *req, void *user)
{
    server_t *sv = user;
    sv->requests++;
    if (!sv->answer)
        return;
    marie_pose_cov_t pose = {.utime = 5, .frame = "map", .pose = {3.0, 4.0, 0.5}};
    uint8_t buf[256];
    int len = marie_pose_cov_t_encode(buf, 0, sizeof buf, &pose);
    marie_pull_reply_t r = {
        .utime = marie_wall_us(), .request_id = req->request_id, .channel = req->channel,
        .status = sv->answer == 1 ? MARIE_PULL_REPLY_T_STATUS_OK : MARIE_PULL_REPLY_T_STATUS_EMPTY,
        .age_us = 1234, .fingerprint = marie_type_pose_cov_t.hash(), .size = sv->answer == 1 ? len : 0, .data = buf,
    };
    marie_pull_reply_t_publish(sv->lcm, req->reply_channel, &r);
}

static void on_server_fd(marie_loop_t *loop, int fd, short revents, void *user)
{
    lcm_handle_timeout(((server_t *)user)->lcm, 0);
}

static void pull_gets_the_newest_value_or_times_out(void **state)
{
    rx_state_t s = {0};
    marie_component_t *c = make(&rx_def, "puller", &s);
    server_t sv = {lcm_create(NULL), 0, 1};
    marie_pull_request_t_subscription_t *sub = marie_pull_request_t_subscribe(sv.lcm, "T_LATEST.PULL", on_request, &sv);
    /* The server shares the component's loop so a blocking pull lets it answer. */
    marie_loop_add_fd(marie_component_loop(c), lcm_get_fileno(sv.lcm), POLLIN, on_server_fd, &sv);
    marie_pose_cov_t got;
    int64_t age = 0;
    assert_int_equal(marie_port_pull(marie_port(c, "latest"), &got, 2000, &age), 0);
    assert_true(got.pose.x == 3.0 && got.pose.y == 4.0);
    assert_string_equal(got.frame, "map");
    assert_int_equal(age, 1234);
    marie_pose_cov_t_decode_cleanup(&got);
    sv.answer = 2;
    assert_fails(marie_port_pull(marie_port(c, "latest"), &got, 2000, &age), ENODATA);
    sv.answer = 0;
    int64_t t0 = marie_mono_us();
    assert_fails(marie_port_pull(marie_port(c, "latest"), &got, 100, &age), ETIMEDOUT);
    assert_true(marie_mono_us() - t0 >= 100000);
    assert_int_equal(sv.requests, 3);
    assert_int_equal(marie_component_counter(c, "pull_timeouts"), 1);
    /* Pulling a push port is a usage error. */
    assert_fails(marie_port_pull(marie_port(c, "pose"), &got, 10, &age), EINVAL);
    marie_loop_remove_fd(marie_component_loop(c), lcm_get_fileno(sv.lcm));
    marie_pull_request_t_unsubscribe(sv.lcm, sub);
    lcm_destroy(sv.lcm);
    marie_component_destroy(c);
}

typedef struct {
    int calls, status;
    double x;
} async_t;

static void on_pulled(marie_component_t *c, marie_port_t *p, int status, const void *msg, int64_t age, void *user)
{
    async_t *a = user;
    a->calls++;
    a->status = status;
    if (msg)
        a->x = ((const marie_pose_cov_t *)msg)->pose.x;
}

static void async_pull_calls_back_exactly_once(void **state)
{
    rx_state_t s = {0};
    marie_component_t *c = make(&rx_def, "puller2", &s);
    server_t sv = {lcm_create(NULL), 0, 1};
    marie_pull_request_t_subscription_t *sub = marie_pull_request_t_subscribe(sv.lcm, "T_LATEST.PULL", on_request, &sv);
    marie_loop_add_fd(marie_component_loop(c), lcm_get_fileno(sv.lcm), POLLIN, on_server_fd, &sv);
    async_t a = {0}, t = {0};
    assert_int_equal(marie_port_pull_async(marie_port(c, "latest"), 2000, on_pulled, &a), 0);
    marie_component_t *cs[1] = {c};
    spin(cs, 1, 300);
    assert_int_equal(a.calls, 1);
    assert_int_equal(a.status, 0);
    assert_true(a.x == 3.0);
    sv.answer = 0;
    assert_int_equal(marie_port_pull_async(marie_port(c, "latest"), 50, on_pulled, &t), 0);
    spin(cs, 1, 300);
    assert_int_equal(t.calls, 1);
    assert_int_equal(t.status, ETIMEDOUT);
    marie_loop_remove_fd(marie_component_loop(c), lcm_get_fileno(sv.lcm));
    marie_pull_request_t_unsubscribe(sv.lcm, sub);
    lcm_destroy(sv.lcm);
    marie_component_destroy(c);
}

/* ---- a channel on shared memory (the system file's transports:) ---- */

typedef struct {
    int got, intact;
} grid_rx_t;

/* Cell i of message k holds (i * 7 + k) % 101: the receiver can tell a whole grid from a torn one. */
static void fill_grid(marie_occupancy_grid_t *g, int8_t *cells, int w, int h, int k)
{
    *g = (marie_occupancy_grid_t){.utime = k + 1, .resolution = 0.05f, .width = w, .height = h, .ncells = w * h,
                                  .cells = cells};
    for (int i = 0; i < w * h; i++)
        cells[i] = (int8_t)((i * 7 + k) % 101);
}

static void on_grid(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    grid_rx_t *s = marie_component_user(c);
    const marie_occupancy_grid_t *g = msg;
    int k = (int)g->utime - 1, ok = g->ncells == g->width * g->height;
    for (int i = 0; ok && i < g->ncells; i++)
        ok = g->cells[i] == (int8_t)((i * 7 + k) % 101);
    s->got++;
    s->intact += ok;
}

static int grid_rx_init(marie_component_t *c) { return marie_port_on_message(marie_port(c, "map"), on_grid); }

static const marie_port_spec_t grid_tx_ports[] = {
    {"map", &marie_type_occupancy_grid_t, MARIE_OUT, MARIE_PUSH, "T_GRID"},
    {0},
};
static const marie_port_spec_t grid_rx_ports[] = {
    {"map", &marie_type_occupancy_grid_t, MARIE_IN, MARIE_PUSH, "T_GRID"},
    {0},
};
static const marie_component_def_t grid_tx_def = {.kind = "gridtx", .ports = grid_tx_ports};
static const marie_component_def_t grid_rx_def = {.kind = "gridrx", .ports = grid_rx_ports, .on_init = grid_rx_init};

typedef struct {
    int whole, notices;
} spy_t;

static void on_spy(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    spy_t *s = user;
    if (strcmp(ch, "T_GRID") == 0)
        s->whole++;
    else
        s->notices++;
}

static void spin_spy(marie_component_t **cs, int n, lcm_t *spy, int ms)
{
    spin(cs, n, ms);
    while (lcm_handle_timeout(spy, 10) > 0)
        ;
}

/* cs[0] publishes `count` grids of `ncells` (cells 0..k-1 of the pattern), spinning cs[0..n). */
static void publish_grids(marie_component_t **cs, int n, lcm_t *spy, int8_t *cells, int ncells, int count)
{
    marie_occupancy_grid_t g;
    for (int k = 0; k < count; k++) {
        fill_grid(&g, cells, ncells, 1, k);
        assert_int_equal(marie_port_publish(marie_port(cs[0], "map"), &g), 0);
        spin_spy(cs, n, spy, 50);
    }
    spin_spy(cs, n, spy, 200);
}

/* A grid sender, a reader, and a reader that plays another host, on a ring of four slots. */
static const char grid_system[] = "system: shmports\n"
                                  "transports:\n"
                                  "  T_GRID: {kind: shm, max_size: 1000000, slots: 4}\n"
                                  "components:\n"
                                  "  tx: {exec: /bin/true}\n"
                                  "  rx: {exec: /bin/true}\n"
                                  "  far: {exec: /bin/true}\n";

static void shm_transport_carries_large_messages_and_lcm_sees_notices(void **state)
{
    char file[] = "/tmp/marie-test-shm-XXXXXX.yaml";
    assert_int_equal(test_write_temp(file, 5, grid_system), 0);
    lcm_t *spy = lcm_create(marie_default_url());   /* the components' bus, with its receive buffer */
    spy_t sp = {0};
    lcm_subscribe(spy, "T_GRID(\\.SHM)?", on_spy, &sp);
    grid_rx_t rx = {0}, far = {0};
    marie_component_t *cs[3] = {make_in(file, &grid_tx_def, "tx", NULL), make_in(file, &grid_rx_def, "rx", &rx)};
    enum { W = 960, H = 960 };      /* 921 600 cells: a 640 x 480 RGB image's size */
    int8_t *cells = malloc((size_t)W * H * 2);
    marie_occupancy_grid_t g;
    /* What marie-ca asks to put its Mailboxes and Splitters on the ring too. */
    assert_int_equal(marie_component_shm_max(cs[1], "T_GRID"), 1000000);
    assert_int_equal(marie_component_shm_max(cs[1], "T_OTHER"), 0);
    publish_grids(cs, 2, spy, cells, W * H, 5);
    /* Every grid arrived whole through the ring; LCM carried only the notices. */
    assert_int_equal(rx.got, 5);
    assert_int_equal(rx.intact, 5);
    assert_int_equal(sp.notices, 5);
    assert_int_equal(sp.whole, 0);
    /* A message larger than the transport allows is refused and counted, not cut. */
    fill_grid(&g, cells, W, 2 * H, 0);
    assert_fails(marie_port_publish(marie_port(cs[0], "map"), &g), EMSGSIZE);
    assert_int_equal(marie_component_counter(cs[0], "publish_too_big"), 1);
    /* A subscriber on another host cannot map the ring: it asks, and the grids come on LCM too. */
    setenv("MARIE_SHM_HOST", "another-host", 1);
    cs[2] = make_in(file, &grid_rx_def, "far", &far);
    unsetenv("MARIE_SHM_HOST");
    publish_grids(cs, 3, spy, cells, W * H, 6);
    assert_int_equal(rx.got, 11);
    assert_int_equal(rx.intact, 11);
    assert_true(far.got >= 4);      /* from the one after its first request on */
    assert_int_equal(far.intact, far.got);
    assert_int_equal(sp.whole, far.got);
    assert_int_equal(marie_component_counter(cs[1], "shm_overwritten"), 0);
    /* A reader that stalls while ten grids go through four slots: the six overwritten are
     * counted, the four still there arrive whole (decoded in place), none torn. */
    marie_occupancy_grid_t big;
    for (int k = 0; k < 10; k++) {
        fill_grid(&big, cells, W * H, 1, 20 + k);
        assert_int_equal(marie_port_publish(marie_port(cs[0], "map"), &big), 0);
    }
    spin_spy(cs, 3, spy, 300);
    assert_int_equal(rx.got, 15);
    assert_int_equal(rx.intact, 15);
    marie_component_heartbeat(cs[1]);      /* the reader's losses are counted with each heartbeat */
    assert_int_equal(marie_component_counter(cs[1], "shm_overwritten"), 6);
    free(cells);
    for (int i = 0; i < 3; i++)
        marie_component_destroy(cs[i]);
    lcm_destroy(spy);
    unlink(file);
}

/* lcm-gen's decoder reads the LCM copies another host gets: every one a whole grid. */
static void on_grid_copy(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    grid_rx_t *s = user;
    marie_occupancy_grid_t g;
    if (marie_occupancy_grid_t_decode(rb->data, 0, (int)rb->data_size, &g) < 0)
        return;
    int k = (int)g.utime - 1, ok = g.ncells == g.width * g.height && g.resolution == 0.05f;
    for (int i = 0; ok && i < g.ncells; i++)
        ok = g.cells[i] == (int8_t)((i * 7 + k) % 101);
    s->got++;
    s->intact += ok;
    marie_occupancy_grid_t_decode_cleanup(&g);
}

/* A loaned grid is made in the ring and published without a copy: it arrives whole here and, as
 * LCM's copy, on another host; a loan is taken up by the next publish, and refused past max_size
 * or where the channel or the type cannot have one. */
static void a_loaned_message_is_made_in_the_ring(void **state)
{
    char file[] = "/tmp/marie-test-shm-XXXXXX.yaml";
    assert_int_equal(test_write_temp(file, 5, grid_system), 0);
    lcm_t *spy = lcm_create(marie_default_url());
    grid_rx_t rx = {0}, far = {0}, copies = {0};
    lcm_subscribe(spy, "T_GRID", on_grid_copy, &copies);
    setenv("MARIE_SHM_HOST", "another-host", 1);
    marie_component_t *far_c = make_in(file, &grid_rx_def, "far", &far);
    unsetenv("MARIE_SHM_HOST");
    marie_component_t *cs[3] = {make_in(file, &grid_tx_def, "tx", NULL), make_in(file, &grid_rx_def, "rx", &rx), far_c};
    marie_port_t *out = marie_port(cs[0], "map");
    enum { W = 960, H = 960 };
    marie_occupancy_grid_t g;
    spin_spy(cs, 3, spy, 100);      /* far's request for LCM copies reaches the writer */
    for (int k = 0; k < 6; k++) {
        int8_t *cells = marie_port_loan(out, (size_t)W * H);
        assert_non_null(cells);
        fill_grid(&g, cells, W, H, k);
        assert_int_equal(marie_port_publish(out, &g), 0);
        spin_spy(cs, 3, spy, 50);
    }
    spin_spy(cs, 3, spy, 200);
    assert_int_equal(rx.got, 6);
    assert_int_equal(rx.intact, 6);
    assert_true(far.got >= 4);
    assert_int_equal(far.intact, far.got);
    assert_int_equal(copies.got, far.got);
    assert_int_equal(copies.intact, copies.got);
    /* A loan holds a smaller grid than it could; one not published is taken up by the next. */
    int8_t *cells = marie_port_loan(out, (size_t)W * H), *mine = malloc((size_t)W * H);
    fill_grid(&g, cells, W, H / 2, 10);
    assert_int_equal(marie_port_publish(out, &g), 0);
    assert_non_null(marie_port_loan(out, 100));
    fill_grid(&g, mine, W, H, 11);      /* not the loan: encoded into the same slot */
    assert_int_equal(marie_port_publish(out, &g), 0);
    spin_spy(cs, 3, spy, 200);
    assert_int_equal(rx.got, 8);
    assert_int_equal(rx.intact, 8);
    /* A length past the loan is refused and counted; so is a loan past max_size, or where there
     * can be none (a plain LCM channel, a type with no byte array last). */
    cells = marie_port_loan(out, 1000);
    fill_grid(&g, cells, 1000, 1, 12);
    g.ncells = 2000;
    assert_fails(marie_port_publish(out, &g), EINVAL);
    assert_int_equal(marie_component_counter(cs[0], "publish_failed"), 1);
    assert_null(marie_port_loan(out, 1000000));
    assert_int_equal(errno, EMSGSIZE);
    marie_component_t *plain = make(&tx_def, "plain", NULL);
    assert_null(marie_port_loan(marie_port(plain, "pose"), 10));
    assert_int_equal(errno, ENOTSUP);
    spin_spy(cs, 3, spy, 100);
    assert_int_equal(rx.got, 8);
    free(mine);
    marie_component_destroy(plain);
    for (int i = 0; i < 3; i++)
        marie_component_destroy(cs[i]);
    lcm_destroy(spy);
    unlink(file);
}

/* A component's loop spins as `sched: {spin_us}` in its entry says, except on the simulator's
 * clock. */
static void a_component_spins_as_its_system_file_says(void **state)
{
    char file[] = "/tmp/marie-test-spin-XXXXXX.yaml";
    assert_int_equal(test_write_temp(file, 5, "system: spin\n"
                                              "components:\n"
                                              "  fast: {exec: /bin/true, sched: {spin_us: 150}}\n"
                                              "  calm: {exec: /bin/true}\n"
                                              "profiles:\n  sim: {clock: sim}\n"),
                     0);
    marie_component_t *fast = make_in(file, &rx_def, "fast", NULL), *calm = make_in(file, &rx_def, "calm", NULL);
    marie_component_t *sim = started(&rx_def, 7, (char *[]){"rx", "--system", file, "--name", "fast", "--profile", "sim"}, NULL);
    assert_int_equal(marie_loop_spin(marie_component_loop(fast)), 150);
    assert_int_equal(marie_loop_spin(marie_component_loop(calm)), 0);
    assert_int_equal(marie_loop_spin(marie_component_loop(sim)), 0);
    marie_component_destroy(fast);
    marie_component_destroy(calm);
    marie_component_destroy(sim);
    unlink(file);
}

int main(void)
{
    marie_log_set_threshold(MARIE_LOG_ERROR);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(push_delivers_typed_messages_and_drops_mistyped_ones),
        cmocka_unit_test(pull_gets_the_newest_value_or_times_out),
        cmocka_unit_test(async_pull_calls_back_exactly_once),
        cmocka_unit_test(shm_transport_carries_large_messages_and_lcm_sees_notices),
        cmocka_unit_test(a_loaned_message_is_made_in_the_ring),
        cmocka_unit_test(a_component_spins_as_its_system_file_says),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
