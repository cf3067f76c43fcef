// bench_mapper_radish: the mapper on real robots' logs (tests/data/radish, CARMEN, read as `marie
// log import carmen` reads them) with the robot's own odometry and the default parameters, fed as
// marie-mapper feeds it, as fast as it goes: per log the mean relation error over 1 m of path and
// the ATE against GMapping's corrected poses (a reference, not ground truth), the p99 time of a
// scan that closed no loop, the slowest closure (optimization and re-render included), and how
// many times faster than the robot's own clock it maps. Each row's baseline is the goal (0.06 m,
// 0.15 m, 10 ms, 100 ms, 5x real time): a ratio at most 1 (at least 1 for speed) meets it. The
// nine logs take about 15 s of CPU (35 s on two loaded cores). docs/mapping.md, "Real robots'
// logs".
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <zlib.h>

extern "C" {
#include "bench/bench.h"
#include "map/trajeval.h"
#include "tests/mapper/replay.h"
#include "tools/log/carmen.h"
}

namespace {

const char *const nine[] = { "aces", "belgioioso", "csail", "edmonton", "fhw", "freiburg-101", "intel", "orebro", "seattle" };

bool read_lines(const std::string &path, std::vector<std::string> *lines)
{
    gzFile f = gzopen(path.c_str(), "rb");
    if (!f)
        return false;
    std::vector<char> buf(4 << 20);
    while (gzgets(f, buf.data(), (int)buf.size())) {
        std::string l(buf.data());
        while (!l.empty() && (l.back() == '\n' || l.back() == '\r'))
            l.pop_back();
        lines->push_back(l);
    }
    gzclose(f);
    return true;
}

struct Feed {
    replay_t *rp = nullptr;
    std::vector<traj_pose_t> ref;
    int64_t first = -1, last = 0;
};

void on_msg(void *user, const carmen_msg_t *m)
{
    Feed *f = static_cast<Feed *>(user);
    if (f->first < 0)
        f->first = m->utime;
    f->last = m->utime;
    if (m->kind == CARMEN_ODOMETRY) {
        replay_odometry(f->rp, m->utime, m->pose);
        return;
    }
    marie_laser_scan_t s{};
    s.utime = m->utime;
    s.angle_min = (float)m->angle_min;
    s.angle_increment = (float)m->angle_increment;
    s.range_max = (float)m->range_max;
    s.nranges = m->n;
    s.ranges = const_cast<float *>(m->ranges);
    replay_laser(f->rp, &s);
    if (m->has_reference)
        f->ref.push_back({ m->utime, m->reference[0], m->reference[1], m->reference[2] });
}

int map_log(const char *name)
{
    std::vector<std::string> lines;
    std::string path = std::string("tests/data/radish/") + name + "-corrected.log.gz";
    if (!read_lines(path, &lines)) {
        fprintf(stderr, "bench_mapper_radish: cannot read %s\n", path.c_str());
        return -1;
    }
    slam_params_t p;
    slam_params_default(&p);
    const double start[3] = { 0, 0, 0 };
    Feed f;
    f.rp = replay_create(&p, start);
    carmen_opts_t o = CARMEN_OPTS_DEFAULT;
    carmen_t *c = carmen_create(&o, on_msg, &f);
    if (!f.rp || !c)
        return -1;
    for (const std::string &l : lines)
        carmen_survey(c, l.c_str());
    carmen_begin(c);
    for (const std::string &l : lines)
        carmen_line(c, l.c_str(), path.c_str(), nullptr, 0);
    bool log_times = carmen_stats(c)->log_times;
    carmen_destroy(c);

    size_t n;
    const replay_scan_t *s = replay_scans(f.rp, &n);
    std::vector<traj_pose_t> est, pe(n), pr(n);
    for (size_t i = 0; i < n; i++)
        est.push_back({ s[i].utime, s[i].pose[0], s[i].pose[1], s[i].pose[2] });
    size_t np = trajeval_pair(est.data(), n, f.ref.data(), f.ref.size(), 0, pe.data(), pr.data());
    trajeval_t e;
    const double d[1] = { 1 };
    replay_times_t t;
    replay_times(f.rp, &t);
    const std::string b = "bench_mapper_radish";
    if (trajeval_run(pe.data(), pr.data(), np, d, 1, &e) == 0) {
        bench_row(b.c_str(), (std::string(name) + " relation error 1 m").c_str(), e.rel[0].trans_mean, "m", 0.06);
        bench_row(b.c_str(), (std::string(name) + " ATE").c_str(), e.ate_rms, "m", 0.15);
    }
    bench_row(b.c_str(), (std::string(name) + " scan p99").c_str(), t.p99, "ms", 10);
    bench_row(b.c_str(), (std::string(name) + " slowest closure").c_str(), t.closure_max, "ms", 100);
    if (log_times && t.total_s > 0)
        bench_row(b.c_str(), (std::string(name) + " speed").c_str(), (double)(f.last - f.first) / 1e6 / t.total_s,
                  "x real time", 5);
    replay_destroy(f.rp);
    return 0;
}

}  // namespace

int main()
{
    int rc = 0;
    for (const char *name : nine)
        rc |= map_log(name) < 0;
    return rc;
}
