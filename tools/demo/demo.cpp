// marie-demo: runs the robot application in simulation under the managers, shows progress and
// ends with a summary, an LCM log and a PNG of the map with true and estimated trajectories.
// --mission explore first maps the world from nothing (the explore profile), saves the map,
// judges it against the world, and runs the navigation mission on it.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <fcntl.h>
#include <getopt.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tools/demo/demo.h"

extern "C" {
#include "map/mapeval.h"
#include "core/config.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "core/version.h"
}

extern char **environ;

namespace marie_demo {

pid_t Demo::spawn(const std::vector<std::string> &args, const std::string &log)
{
    std::vector<char *> argv;
    for (const auto &a : args)
        argv.push_back(const_cast<char *>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid = 0;
    int rc = posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        fprintf(stderr, "demo: cannot start %s: %s\n", argv[0], strerror(rc));
        return 0;
    }
    return pid;
}

int Demo::run_cmd(const std::vector<std::string> &args, const std::string &log)
{
    pid_t pid = spawn(args, log);
    int status = 0;
    if (!pid || waitpid(pid, &status, 0) < 0)
        return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

int Demo::up(const std::string &profile)
{
    printf("demo: bringing up %s, profile %s\n", opt_.system.c_str(), profile.c_str());
    int rc = run_cmd({bin_ + "/marie", "--key", opt_.out + "/key", "--timeout", "30", "up", opt_.system, "--profile",
                      profile},
                     opt_.out + "/marie.log");
    up_ = true;
    if (rc != 0)
        fprintf(stderr, "demo: marie up failed (exit %d); see %s/marie.log and %s/am-*.log\n", rc, opt_.out.c_str(),
                opt_.out.c_str());
    return rc;
}

void Demo::down()
{
    if (up_)
        run_cmd({bin_ + "/marie", "--key", opt_.out + "/key", "--timeout", "10", "down"}, opt_.out + "/marie.log");
    up_ = false;
}

void Demo::shutdown()
{
    down();
    for (pid_t p : ams_)
        kill(p, SIGTERM);
    for (pid_t p : ams_)
        waitpid(p, nullptr, 0);
    ams_.clear();
    if (logger_) {
        kill(logger_, SIGINT);
        waitpid(logger_, nullptr, 0);
        logger_ = 0;
    }
    for (auto &h : hosts_)
        marie_am_status_t_destroy(h.second);
    hosts_.clear();
    marie_loop_destroy(loop_);         // default SIGINT/SIGTERM handling again
    loop_ = nullptr;
    if (lcm_)
        marie_bus_destroy(lcm_);
    lcm_ = nullptr;
}

void Demo::on_raw(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    static_cast<Demo *>(user)->handle(channel, rb->data, rb->data_size);
}

double Demo::loc_error_at(int64_t t, double x, double y, bool *ok) const
{
    // Ground truth is published at 50 Hz of sim time: interpolate at the estimate's time.
    *ok = false;
    if (truth_.size() < 2 || t < truth_.front().t || t > truth_.back().t)
        return 0;
    auto it = std::lower_bound(truth_.begin(), truth_.end(), t, [](const Sample &s, int64_t v) { return s.t < v; });
    if (it == truth_.begin())
        ++it;
    const Sample &b = *it, &a = *(it - 1);
    double f = b.t > a.t ? double(t - a.t) / double(b.t - a.t) : 0;
    *ok = true;
    return std::hypot(a.x + f * (b.x - a.x) - x, a.y + f * (b.y - a.y) - y);
}

void Demo::handle(const char *channel, const void *data, size_t len)
{
    if (!strcmp(channel, "SIM_TRUTH")) {
        marie_pose_cov_t m;
        if (marie_decode_checked(&marie_type_pose_cov_t, data, len, &m) < 0)
            return;
        truth_.push_back({m.utime, m.pose.x, m.pose.y});
        sim_now_ = std::max(sim_now_, m.utime);
        marie_pose_cov_t_decode_cleanup(&m);
        if (running_ && opt_.estop_after_goal > 0)
            estop_tick();
    } else if (!strcmp(channel, "POSE")) {
        marie_pose_cov_t m;
        if (marie_decode_checked(&marie_type_pose_cov_t, data, len, &m) < 0)
            return;
        estimate_.push_back({m.utime, m.pose.x, m.pose.y});
        bool ok;
        double e = loc_error_at(m.utime, m.pose.x, m.pose.y, &ok);
        if (ok)
            errors_.push_back(e);
        marie_pose_cov_t_decode_cleanup(&m);
    } else if (!strcmp(channel, "ESTOP")) {
        marie_estop_t m;
        if (marie_decode_checked(&marie_type_estop_t, data, len, &m) < 0)
            return;
        if (estop_pressed_at_ && !estop_applied_at_ && m.pressed && !strcmp(m.source, "sim")) {
            estop_applied_at_ = m.utime;
            printf("demo: the simulator's e-stop went down at sim %.2f s\n", m.utime / 1e6);
        }
        marie_estop_t_decode_cleanup(&m);
    } else if (!strcmp(channel, "GOAL")) {
        marie_goal_t g;
        if (marie_decode_checked(&marie_type_goal_t, data, len, &g) < 0)
            return;
        if (!goals_.count(g.id))
            goal_order_.push_back(g.id);
        goals_[g.id] = g.pose;
        current_goal_ = g.name;
        marie_goal_t_decode_cleanup(&g);
    } else if (!strcmp(channel, "MISSION_STATE")) {
        marie_mission_state_t s;
        if (marie_decode_checked(&marie_type_mission_state_t, data, len, &s) < 0)
            return;
        ngoals_ = s.ngoals;
        reached_ = missed_ = 0;
        for (int i = 0; i < s.ngoals; i++) {
            reached_ += s.goal_states[i] == MARIE_MISSION_STATE_T_STATE_REACHED;
            missed_ += s.goal_states[i] == MARIE_MISSION_STATE_T_STATE_MISSED;
        }
        marie_mission_state_t_decode_cleanup(&s);
    } else if (!strcmp(channel, "MARIE_EVENT")) {
        marie_event_t e;
        if (marie_decode_checked(&marie_type_event_t, data, len, &e) < 0)
            return;
        std::string kind = e.kind;
        if (kind == "mission_done")
            mission_done_ = true;
        explore_done_ |= exploring_ && kind == "explore_done";
        frontiers_ += exploring_ && kind == "frontier_goal";
        given_up_ += exploring_ && kind == "frontier_given_up";
        if (!opt_.quiet && (kind.rfind("goal_", 0) == 0 || kind.rfind("frontier_", 0) == 0 || kind == "explore_done" ||
                            kind == "mission_done" || kind == "gave_up" || e.severity >= MARIE_EVENT_T_SEV_ERROR))
            printf("demo: [%s] %s\n", e.source, e.text);
        marie_event_t_decode_cleanup(&e);
    } else if (!strcmp(channel, "MARIE_AM_STATUS")) {
        marie_am_status_t *s = static_cast<marie_am_status_t *>(calloc(1, sizeof *s));
        if (marie_decode_checked(&marie_type_am_status_t, data, len, s) < 0) {
            free(s);
            return;
        }
        auto it = hosts_.find(s->host);
        if (it != hosts_.end())
            marie_am_status_t_destroy(it->second);
        hosts_[s->host] = s;
    } else if (!strcmp(channel, "MARIE_HEARTBEAT")) {
        marie_heartbeat_t hb;
        if (marie_decode_checked(&marie_type_heartbeat_t, data, len, &hb) < 0)
            return;
        for (int i = 0; i < hb.ncounters; i++)
            if (!strcmp(hb.counters[i].name, "collisions"))
                collisions_ = std::max(collisions_, hb.counters[i].value);
        marie_heartbeat_t_decode_cleanup(&hb);
    }
}

// restarts: every host's component restarts, as its manager last reported them.
int Demo::restarts() const
{
    int n = 0;
    for (auto &h : hosts_)
        for (int i = 0; i < h.second->ncomponents; i++)
            n += h.second->components[i].restarts;
    return n;
}

void Demo::progress(bool final)
{
    int running = 0, total = 0;
    for (auto &h : hosts_)
        for (int i = 0; i < h.second->ncomponents; i++) {
            total++;
            running += !strcmp(h.second->components[i].state, "running");
        }
    double cpu = 0, rss = 0;
    for (auto &h : hosts_) {
        cpu += h.second->am_cpu;
        rss += h.second->am_rss / 1048576.0;
        for (int i = 0; i < h.second->ncomponents; i++) {
            cpu += h.second->components[i].cpu;
            rss += h.second->components[i].rss / 1048576.0;
        }
    }
    if (running == total && total > 0) {
        cpu_sum_ += cpu;
        cpu_samples_++;
        rss_peak_mb_ = std::max(rss_peak_mb_, rss);
    }
    double err = errors_.empty() ? NAN : errors_.back();
    double wall = (marie_mono_us() - start_mono_) / 1e6;
    if ((!opt_.quiet || final) && exploring_)
        printf("demo: %5.1f s (sim %6.1f s) | exploring: frontier %d, %d given up | pose error %.2f m | "
               "components %d/%d running | restarts %d\n",
               wall, sim_now_ / 1e6, frontiers_, given_up_, err, running, total, restarts());
    else if ((!opt_.quiet || final) && (total == 0 || ngoals_ == 0 || std::isnan(err)))
        // Before the first mission state and pose: say what is awaited, not "goal 1 of 0 ... nan".
        printf("demo: %5.1f s (sim %6.1f s) | starting: components %d/%d running%s%s\n", wall, sim_now_ / 1e6,
               running, total, ngoals_ ? "" : ", waiting for the mission's goals",
               std::isnan(err) ? ", waiting for the first pose estimate" : "");
    else if (!opt_.quiet || final)
        printf("demo: %5.1f s (sim %6.1f s) | goal %d of %d%s%s | reached %d | loc error %.2f m | "
               "components %d/%d running | restarts %d\n",
               wall, sim_now_ / 1e6, std::min(reached_ + missed_ + 1, std::max(ngoals_, 1)), ngoals_,
               current_goal_.empty() ? "" : " ", current_goal_.c_str(), reached_, err, running, total, restarts());
    fflush(stdout);
}

void Demo::on_progress_timer(marie_loop_t *, marie_timer_t *, int64_t, void *user)
{
    static_cast<Demo *>(user)->progress(false);
}

void Demo::on_chaos_timer(marie_loop_t *, marie_timer_t *, int64_t, void *user)
{
    static_cast<Demo *>(user)->chaos_tick();
}

void Demo::on_signal(marie_loop_t *, int, void *user)
{
    static_cast<Demo *>(user)->interrupted_ = true;
}

void Demo::chaos_tick()
{
    // SIGKILL a random running component other than the simulator (and the Mailbox, the
    // SharedMap and the drivers are fair game: the managers must bring them back). Sorted by
    // name, so a seed draws the same names wherever the same components run.
    std::vector<std::pair<std::string, int>> victims;
    for (auto &h : hosts_)
        for (int i = 0; i < h.second->ncomponents; i++) {
            const marie_am_component_status_t &c = h.second->components[i];
            if (c.pid > 0 && !strcmp(c.state, "running") && strcmp(c.name, "sim") != 0)
                victims.push_back({c.name, c.pid});
        }
    if (victims.empty())
        return;
    std::sort(victims.begin(), victims.end());
    auto v = victims[demo_chaos_pick(&chaos_, victims.size())];
    for (auto &c : victims)
        if (kills_ == 0 && c.first == opt_.chaos_first)
            v = c;
    if (kill(v.second, SIGKILL) == 0) {
        kills_++;
        killed_.push_back(v.first);
        printf("demo: chaos: SIGKILL %s (pid %d)\n", v.first.c_str(), v.second);
    }
}

void Demo::estop_tick()
{
    auto press = [this](bool on) {
        marie_estop_t e = {sim_now_, on, const_cast<char *>("demo")};
        marie_estop_t_publish(lcm_, "SIM_ESTOP", &e);
    };
    if (!estop_pressed_at_ && reached_ >= opt_.estop_after_goal && truth_.size() > 10) {
        // Only once the robot is moving again towards the next goal.
        const Sample &a = truth_[truth_.size() - 6], &b = truth_.back();
        double v = std::hypot(b.x - a.x, b.y - a.y) / ((b.t - a.t) / 1e6 + 1e-9);
        if (v > 0.2) {
            press(true);
            estop_pressed_at_ = sim_now_;
            printf("demo: e-stop pressed at sim %.2f s (robot at %.2f m/s)\n", sim_now_ / 1e6, v);
        }
    } else if (estop_applied_at_ && !estop_stopped_at_ && truth_.size() > 3) {
        // Timed from the button in the simulated world, not from the demo's request: at ~10x
        // real time a 20 ms delivery delay of the request would be 0.2 s of simulated time.
        const Sample &a = truth_[truth_.size() - 2], &b = truth_.back();
        double v = std::hypot(b.x - a.x, b.y - a.y) / ((b.t - a.t) / 1e6 + 1e-9);
        if (b.t > estop_applied_at_ && v < 0.02) {
            estop_stopped_at_ = b.t;
            estop_stop_s_ = (estop_stopped_at_ - estop_applied_at_) / 1e6;
            printf("demo: robot stopped %.2f s (sim) after the e-stop\n", estop_stop_s_);
        }
    } else if (estop_stopped_at_ && !estop_released_at_ && sim_now_ - estop_stopped_at_ > 2000000) {
        press(false);
        estop_released_at_ = sim_now_;
        printf("demo: e-stop released\n");
    }
}

// Installed (make install), the system file and what its relative paths name (maps, worlds) are
// in <bin>/../share/marie: run from there when the file is not found here, the output directory
// kept where it was asked for, and the simulator's phrases from share/marie/sounds.
int Demo::use_installed_data()
{
    std::string share = bin_ + "/../share/marie";
    if (access(opt_.system.c_str(), R_OK) == 0 || opt_.system[0] == '/' ||
        access((share + "/" + opt_.system).c_str(), R_OK) != 0)
        return 0;
    char cwd[4096];
    if (!getcwd(cwd, sizeof cwd))
        return -1;
    if (opt_.out[0] != '/')
        opt_.out = std::string(cwd) + "/" + opt_.out;
    run_cmd({"mkdir", "-p", opt_.out}, "/dev/null");
    if (access((share + "/sounds").c_str(), R_OK) == 0)
        setenv("MARIE_SOUNDS", (share + "/sounds").c_str(), 0);
    printf("demo: %s from %s\n", opt_.system.c_str(), share.c_str());
    return chdir(share.c_str());
}

// Key, logger and one manager per host: what both missions run under.
int Demo::start()
{
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return 1;
    self[n] = 0;
    bin_ = std::string(self).substr(0, std::string(self).find_last_of('/'));
    if (use_installed_data() < 0)
        return 1;
    std::string path = bin_ + ":" + (getenv("PATH") ? getenv("PATH") : "/usr/bin:/bin");
    setenv("PATH", path.c_str(), 1);
    mkdir(opt_.out.c_str(), 0755);
    if (opt_.mission == "explore") {
        // The navigation mission runs on the map the robot builds: the system file's localizer
        // and planner read MARIE_MAP, which the managers pass on to them.
        char *abs = realpath(opt_.out.c_str(), nullptr);
        if (!abs)
            return 1;
        setenv("MARIE_MAP", (std::string(abs) + "/explored.yaml").c_str(), 1);
        free(abs);
    } else {
        auto loc = component_params(opt_.profile.c_str(), "localizer");
        occmap_t *m = load_occmap(loc.count("map") ? loc["map"] : "sim/worlds/office.yaml");
        if (!m)
            return 2;
        draw_map(m);
        occmap_destroy(m);
    }
    // Each demo starts a fresh mission: no SharedMap or manager state from an earlier run.
    std::string state = opt_.out + "/state";
    run_cmd({"rm", "-rf", state}, "/dev/null");
    mkdir(state.c_str(), 0755);
    unlink((opt_.out + "/key").c_str());
    if (run_cmd({bin_ + "/marie", "keygen", opt_.out + "/key"}, opt_.out + "/marie.log") != 0) {
        fprintf(stderr, "demo: cannot make the order key (see %s/marie.log)\n", opt_.out.c_str());
        return 1;
    }
    start_mono_ = marie_mono_us();
    // marie's URL, read by marie (its 8 MB receive buffer is the queue): a simulation as fast as
    // the computer allows sends truth and poses in bursts, and a lost one bends the trajectory drawn.
    lcm_ = marie_bus_create(marie_default_url());
    loop_ = marie_loop_create();
    if (!lcm_ || !loop_ || marie_loop_add_bus(loop_, lcm_, 64) < 0)
        return 1;
    for (const char *ch : {"SIM_TRUTH", "POSE", "GOAL", "MISSION_STATE", "MARIE_EVENT", "MARIE_AM_STATUS",
                           "MARIE_HEARTBEAT", "ESTOP"})
        marie_bus_subscribe(lcm_, ch, on_raw, this);
    unlink((opt_.out + "/demo.lcm").c_str());
    // Record everything but the particle clouds, which are large and only for the viewer.
    // On marie's URL, with its large receive buffer: on LCM's default one a loaded machine made
    // the logger drop messages (the e-stop request among them).
    logger_ = spawn({"lcm-logger", "-q", std::string("--lcm-url=") + marie_default_url(), "--channel=^(?!PARTICLES$).*",
                     opt_.out + "/demo.lcm"},
                    opt_.out + "/logger.log");
    static const char *const host_names[] = {"onboard1", "onboard2", "onboard3", "laptop"};
    for (int i = 0; i < opt_.hosts && i < 4; i++) {
        std::string dir = state + "/" + host_names[i];
        mkdir(dir.c_str(), 0755);
        ams_.push_back(spawn({bin_ + "/marie-am", "--host", host_names[i], "--state-dir", dir, "--key", opt_.out + "/key"},
                             opt_.out + "/am-" + host_names[i] + ".log"));
    }
    // Orders go to managers that listen: wait until each has reported its status once.
    marie_loop_run_until(loop_, 10000, [](void *u) -> int {
        auto *d = static_cast<Demo *>(u);
        return d->hosts_.size() >= d->ams_.size();
    }, this);
    if (hosts_.size() < ams_.size()) {
        fprintf(stderr, "demo: only %zu of %zu managers answered; see %s/am-*.log\n", hosts_.size(), ams_.size(),
                opt_.out.c_str());
        return 1;
    }
    printf("demo: %d managers running (onboard1-3, laptop)\n", int(ams_.size()));
    marie_loop_catch_signals(loop_, on_signal, this);
    return 0;
}

// What one mission saw, forgotten before the next: the simulator starts over.
void Demo::new_phase()
{
    truth_.clear();
    estimate_.clear();
    errors_.clear();
    goals_.clear();
    goal_order_.clear();
    current_goal_.clear();
    sim_now_ = 0;
    phase_mono_ = marie_mono_us();
}

static int64_t ms_left(int64_t since_us, double limit_s)
{
    double left_s = limit_s - (marie_mono_us() - since_us) / 1e6;
    return left_s <= 0 ? 0 : left_s > 86400 ? 86400000 : int64_t(left_s * 1000);
}

// The explore profile until no reachable frontier is left; then the map is saved, judged
// against the simulator's world, drawn, and everything brought down for the next mission.
int Demo::explore()
{
    new_phase();
    exploring_ = true;
    if (up(opt_.explore_profile) != 0)
        return 1;
    printf("demo: exploring from an empty map\n");
    marie_timer_t *progress_timer = marie_loop_add_wall_timer(loop_, 2000000, on_progress_timer, this);
    progress(false);
    marie_loop_run_until(loop_, int(ms_left(phase_mono_, opt_.explore_timeout_s)), [](void *u) -> int {
        auto *d = static_cast<Demo *>(u);
        return d->interrupted_ || d->explore_done_;
    }, this);
    marie_loop_remove_timer(loop_, progress_timer);
    progress(true);
    double wall_s = (marie_mono_us() - phase_mono_) / 1e6, sim_s = sim_now_ / 1e6;
    if (!explore_done_)     // the map so far is still saved and judged: it shows what went wrong
        fprintf(stderr, "demo: exploration %s after %.0f s\n", interrupted_ ? "interrupted" : "did not end", wall_s);
    std::string yaml = getenv("MARIE_MAP");
    std::string name = yaml.substr(0, yaml.size() - 5);
    occmap_t *built = nullptr;
    if (run_cmd({bin_ + "/marie", "map", "save", name, "--wait", "12"}, opt_.out + "/map-save.log") != 0 ||
        !(built = load_occmap(yaml))) {
        fprintf(stderr, "demo: cannot save the map (see %s/map-save.log)\n", opt_.out.c_str());
        return 1;
    }
    draw_map(built);
    // Judged against the world the simulator ran, from its start pose.
    auto sim = component_params(opt_.explore_profile.c_str(), "sim");
    char world[4096];
    occmap_world_path(sim.count("world") ? sim["world"].c_str() : "office", world, sizeof world);
    double sx = sim.count("start_x") ? atof(sim["start_x"].c_str()) : 2.0;
    double sy = sim.count("start_y") ? atof(sim["start_y"].c_str()) : 15.0;
    occmap_t *truth = load_occmap(world);
    mapeval_judgement_t j = {};
    if (truth)
        mapeval_judge(truth, built, sx, sy, &j);
    occmap_destroy(truth);
    occmap_destroy(built);
    double ate = errors_.empty() ? -1 : rms_of(errors_, nullptr);
    const mapeval_t &raw = j.raw, &al = j.aligned;
    write_png(opt_.out + "/explored.png");
    printf("demo: %s in %.0f s (sim %.0f s): %d frontiers, %d given up, pose RMS %.2f m; map %s against %s: "
           "precision %.2f recall %.2f coverage %.2f (aligned by %.2f m %.2f m %.3f rad: %.2f %.2f %.2f)\n",
           explore_done_ ? "explored" : "NOT explored", wall_s, sim_s, frontiers_, given_up_, ate, yaml.c_str(), world,
           raw.precision, raw.recall, raw.coverage, j.dx, j.dy, j.th, al.precision, al.recall, al.coverage);
    char json[512];
    snprintf(json, sizeof json,
             ", \"explore\": {\"done\": %s, \"wall_s\": %.1f, \"sim_s\": %.1f, \"frontiers\": %d, \"given_up\": %d, \"rms\": %.4f, "
             "\"precision\": %.3f, \"recall\": %.3f, \"coverage\": %.3f, \"aprecision\": %.3f, \"arecall\": %.3f, "
             "\"acoverage\": %.3f}",
             explore_done_ ? "true" : "false", wall_s, sim_s, frontiers_, given_up_, ate, raw.precision, raw.recall, raw.coverage, al.precision,
             al.recall, al.coverage);
    explore_json_ = json;
    if (!explore_done_)
        return 1;
    down();
    // The demo's queue still holds what the exploration sent while marie down ran: take it now,
    // not as the next mission's.
    marie_loop_run_until(loop_, 300, nullptr, nullptr);
    exploring_ = false;
    return 0;
}

// The navigation mission of the profile, to mission_done or the time limit.
int Demo::navigate()
{
    new_phase();
    if (up(opt_.profile) != 0)
        return 1;
    marie_timer_t *progress_timer = marie_loop_add_wall_timer(loop_, 2000000, on_progress_timer, this);
    if (opt_.chaos_s > 0)
        printf("demo: chaos every %g s, seed %llu (--seed %llu draws the same victims)\n", opt_.chaos_s,
               (unsigned long long)chaos_.seed, (unsigned long long)chaos_.seed);
    marie_timer_t *chaos_timer = opt_.chaos_s > 0 ? marie_loop_add_wall_timer(loop_, int64_t(opt_.chaos_s * 1e6),
                                                                              on_chaos_timer, this)
                                                  : nullptr;
    running_ = true;
    progress(false);
    marie_loop_run_until(loop_, int(ms_left(phase_mono_, opt_.timeout_s)), [](void *u) -> int {
        auto *d = static_cast<Demo *>(u);
        return d->interrupted_ || d->mission_done_;
    }, this);
    running_ = false;
    marie_loop_remove_timer(loop_, progress_timer);
    marie_loop_remove_timer(loop_, chaos_timer);
    // Let the last statuses arrive, then stop everything. The mission's final state can come
    // after its mission_done event (it saves to the SharedMap first, 0.3 s when that is down):
    // wait on the clock, bounded, then a little more for the managers' last statuses.
    marie_loop_run_until(loop_, 1500, [](void *u) -> int {
        auto *d = static_cast<Demo *>(u);
        return d->mission_done_ && d->reached_ + d->missed_ >= d->ngoals_;
    }, this);
    // A component killed just before the end is restarted after it: wait (bounded) until the
    // managers report a restart for every kill.
    marie_loop_run_until(loop_, 10000, [](void *u) -> int {
        auto *d = static_cast<Demo *>(u);
        return d->restarts() >= d->kills_;
    }, this);
    marie_loop_run_until(loop_, 100, nullptr, nullptr);
    progress(true);
    double wall = (marie_mono_us() - start_mono_) / 1e6;
    write_png(opt_.out + "/trajectories.png");
    summary(wall);
    printf("demo: log %s/demo.lcm, map %s/trajectories.png, summary %s/summary.json\n", opt_.out.c_str(),
           opt_.out.c_str(), opt_.out.c_str());
    return mission_done_ ? 0 : 1;
}

int Demo::run()
{
    int rc = start();
    if (rc == 0 && opt_.mission == "explore" && (rc = explore()) != 0)
        summary((marie_mono_us() - start_mono_) / 1e6);     // what the exploration reached
    if (rc == 0)
        rc = navigate();
    shutdown();
    return rc;
}

void usage(FILE *out)
{
    fprintf(out, "usage: marie-demo [--system FILE] [--profile P] [--out DIR] [--timeout S] [--chaos S]\n"
                 "                  [--chaos-first NAME] [--seed N] [--estop-after-goal K] [--quiet]\n"
                 "                  [--mission navigate|explore] [--explore-profile P] [--explore-timeout S]\n"
                 "  --mission explore: map the world from nothing first (profile explore), save it as\n"
                 "  OUT/explored.yaml, judge it against the world, then navigate on it (MARIE_MAP)\n");
}

}  // namespace marie_demo

using marie_demo::Demo;
using marie_demo::Options;
using marie_demo::usage;

int main(int argc, char **argv)
{
    marie_version_exit("marie-demo", argc, argv);
    Options o;
    static const struct option opts[] = {
        {"system", required_argument, nullptr, 's'}, {"profile", required_argument, nullptr, 'p'},
        {"out", required_argument, nullptr, 'o'}, {"timeout", required_argument, nullptr, 't'},
        {"chaos", required_argument, nullptr, 'c'}, {"estop-after-goal", required_argument, nullptr, 'e'},
        {"chaos-first", required_argument, nullptr, 'f'}, {"mission", required_argument, nullptr, 'm'},
        {"explore-profile", required_argument, nullptr, 'x'}, {"explore-timeout", required_argument, nullptr, 'T'},
        {"seed", required_argument, nullptr, 'S'}, {"quiet", no_argument, nullptr, 'q'}, {"help", no_argument, nullptr, 'h'}, {nullptr, 0, nullptr, 0},
    };
    int c;
    while ((c = getopt_long(argc, argv, "", opts, nullptr)) != -1) {
        switch (c) {
        case 's': o.system = optarg; break;
        case 'p': o.profile = optarg; break;
        case 'o': o.out = optarg; break;
        case 't': o.timeout_s = atof(optarg); break;
        case 'c': o.chaos_s = atof(optarg); break;
        case 'f': o.chaos_first = optarg; break;
        case 'S': {
            char *end;
            errno = 0;
            o.seed = strtoull(optarg, &end, 0);
            if (errno || end == optarg || *end || optarg[0] == '-') {
                fprintf(stderr, "marie-demo: --seed takes an unsigned integer, not '%s'\n", optarg);
                return 2;
            }
            o.seed_set = true;
            break;
        }
        case 'e': o.estop_after_goal = atoi(optarg); break;
        case 'm': o.mission = optarg; break;
        case 'x': o.explore_profile = optarg; break;
        case 'T': o.explore_timeout_s = atof(optarg); break;
        case 'q': o.quiet = true; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (o.mission != "navigate" && o.mission != "explore") {
        usage(stderr);
        return 2;
    }
    Demo d(o);
    return d.run();
}
