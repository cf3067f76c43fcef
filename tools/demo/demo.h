// marie-demo's driver: the processes it runs, what it sees on the bus, what it reports.
#ifndef MARIE_DEMO_H
#define MARIE_DEMO_H

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <sys/types.h>

#include <lcm/lcm.h>
#include <opencv2/core.hpp>

extern "C" {
#include "map/occmap.h"
#include "core/loop.h"
#include "lcmtypes/marie_types.h"
#include "tools/demo/chaos.h"
}

namespace marie_demo {


struct Sample {
    int64_t t;
    double x, y;
};

struct Options {
    std::string system = "config/spartacus.yaml";
    std::string profile = "sim";
    std::string mission = "navigate";   // or explore: map first (explore_profile), then navigate on it
    std::string explore_profile = "explore";
    std::string out = "build/demo";
    double timeout_s = 170;             // s of wall time for the navigation mission
    double explore_timeout_s = 600;     // ...and for the exploration
    double chaos_s = 0;           // kill a random non-simulator component this often
    std::string chaos_first;      // ...and this one first, when it runs
    uint64_t seed = 0;            // the victims' draw (--seed); a fresh one when not set
    bool seed_set = false;
    int estop_after_goal = 0;     // press the e-stop once this many goals are reached
    int hosts = 4;
    bool quiet = false;
};

class Demo {
public:
    explicit Demo(const Options &o) : opt_(o)
    {
        demo_chaos_init(&chaos_, o.seed_set ? o.seed : demo_chaos_fresh_seed());
    }
    ~Demo() { shutdown(); }

    int run();

private:
    // processes
    pid_t spawn(const std::vector<std::string> &args, const std::string &log);
    int run_cmd(const std::vector<std::string> &args, const std::string &log);
    int start();
    int up(const std::string &profile);
    int use_installed_data();
    void down();
    void shutdown();
    // the two missions
    int explore();
    int navigate();
    void new_phase();
    // bus
    static void on_raw(const lcm_recv_buf_t *rb, const char *channel, void *user);
    void handle(const char *channel, const void *data, size_t len);
    void progress(bool final);
    int restarts() const;
    void chaos_tick();
    void estop_tick();
    static void on_progress_timer(marie_loop_t *, marie_timer_t *, int64_t, void *user);
    static void on_chaos_timer(marie_loop_t *, marie_timer_t *, int64_t, void *user);
    static void on_signal(marie_loop_t *, int, void *user);
    std::map<std::string, std::string> component_params(const char *profile, const char *component);
    void draw_map(const occmap_t *m);
    void write_png(const std::string &path);
    void summary(double wall_s);
    double loc_error_at(int64_t t, double x, double y, bool *ok) const;

    Options opt_;
    std::string bin_;
    std::vector<pid_t> ams_;
    pid_t logger_ = 0;
    lcm_t *lcm_ = nullptr;
    marie_loop_t *loop_ = nullptr;
    bool up_ = false;
    bool running_ = false;      // the mission runs: the e-stop check follows each truth
    bool interrupted_ = false;
    // what we saw
    std::vector<Sample> truth_, estimate_;
    std::vector<double> errors_;
    std::map<int, marie_pose2d_t> goals_;
    std::vector<int> goal_order_;
    std::string current_goal_;
    int ngoals_ = 0, reached_ = 0, missed_ = 0;
    bool mission_done_ = false;
    int64_t sim_now_ = 0;
    // exploration
    bool exploring_ = false, explore_done_ = false;
    int frontiers_ = 0, given_up_ = 0;
    std::string explore_json_;     // its figures, for summary.json
    std::map<std::string, marie_am_status_t *> hosts_;
    int64_t collisions_ = 0;
    int kills_ = 0;
    std::vector<std::string> killed_;
    // e-stop check
    // pressed_at_: when the demo asked, on its view of the clock; applied_at_: when the
    // simulator's button went down (its ESTOP message), from which the stop is timed.
    int64_t estop_pressed_at_ = 0, estop_applied_at_ = 0, estop_stopped_at_ = 0, estop_released_at_ = 0;
    double estop_stop_s_ = -1;
    // map
    cv::Mat map_;
    double res_ = 0.05, ox_ = 0, oy_ = 0;
    demo_chaos_t chaos_{};
    int64_t start_mono_ = 0, phase_mono_ = 0;
    // whole system, from the managers' status: CPU summed over components, RSS summed
    double cpu_sum_ = 0, rss_peak_mb_ = 0;
    int cpu_samples_ = 0;
};

// A map_server pair, errors printed; NULL when it does not load. The caller frees it.
occmap_t *load_occmap(const std::string &yaml);
// Root mean square of v (NaN when empty); *max (if not NULL) gets the largest.
double rms_of(const std::vector<double> &v, double *max);

}  // namespace marie_demo

#endif
